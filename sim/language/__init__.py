"""The maze's language, pure: what a Driver says about its view, what a Commander's words ask for, and where the robot must be for the dialog to be true."""
