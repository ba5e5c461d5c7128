"""What the physics reference run as a method declares to the report (:mod:`drapebench.plugins`): the row runtime
tables give every method's speed-up over, and the rows that measure the reference's distance from itself."""

SPEEDUP_REFERENCE = "pbs"  # the physics reference run as a method: the speed-ups of runtime_vs_error are over it
# the reference's distance from itself, run as methods against the vbd reference (conf/method/<name>.yaml)
REFERENCE_FLOOR = {"pbs_style3d": "the other solver (Style3D)", "pbs_half_dt": "vbd at half the time step of the reference"}

# --quick (a pipeline check): the simulation settles 2 frames, as --quick's reference does (reference.settle_frames),
# not 30 (a tshirt kick took 25-125 s; 392 core-s of CI's quick run)
QUICK = ("method.params.settle_frames=2",)
