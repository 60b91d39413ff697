"""The loop online: a simulation you can step, its sensors, online perception, the Gymnasium environment."""
