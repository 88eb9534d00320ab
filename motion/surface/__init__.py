"""Moving muscle surfaces: rest pose, generated bellies and tendons, binding to the action line, bones."""
