"""The maze's language, pure: what a Driver says about its view, and what a Commander's words ask for."""
