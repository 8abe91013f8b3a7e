"""The database: tables (`app.db.models`) and engine/session setup (`app.db.engine`)."""
