"""The RobotSlang rover client: runs on the Raspberry Pi, streams the camera and executes the
Driver's moves. It speaks only the wire protocol of docs/protocol.md and imports nothing from
the server's packages (app/, sim/, models/)."""

__version__ = "0.1.0"
