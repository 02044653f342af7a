"""Recording and replay of missions (MCAP): io.Recorder, io.Replayer."""
