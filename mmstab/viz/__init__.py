"""Drawing and viewing."""
