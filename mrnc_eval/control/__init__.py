"""Control chain: pure pursuit, skid-steer inverse kinematics, per-side controllers, plant."""
