"""Drawing and viewing: figures, the robot and ground drawn, animations, the browser viewer."""
