"""Toolpaths, G-code programs, the GRBL 1.1 protocol and the streamer."""
