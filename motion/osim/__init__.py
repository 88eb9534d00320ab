"""Reading OpenSim: the model (.osim), its functions and joints, motions (.mot/.sto) and body poses."""
