"""The RobotSlang server: settings, database, trial protocol, websockets, pages and CLI."""
