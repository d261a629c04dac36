"""Running policies in envs, without torch: episodes and their statistics, scripted drivers,
closed-loop deployment on a spiking backend, training replays and video files."""
