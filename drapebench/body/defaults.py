"""Body-sequence constants that import nothing (the config schema reads them without torch)."""

DEFAULT_TRANSITION = 15  # frames (0.5 s at 30 fps) from the rest pose into the motion
# Split by motion kind: kick and stress never appear in training sets; static (a held pose) is in neither.
HELD_OUT_MOTIONS = ("kick", "stress")
