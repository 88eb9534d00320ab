"""Action lines: path points, wrapping over OpenSim wrap objects, lengths and moment arms."""
