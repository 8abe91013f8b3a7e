"""The server's side of the rover loop: sim's tracker, perception and particle filter wired to live trials."""
