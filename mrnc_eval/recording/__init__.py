"""The simulator's edge: drive the mission in closed loop (control/), sample every sensor with the
models of sim/, and write the log as the robot's drivers do (io/writers.py). sim/ stays pure."""
