"""HTTP pages and websocket endpoints."""
