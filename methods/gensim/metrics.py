"""The diagnostics GenSim reports beside the library's metrics (:meth:`methods.gensim.GenSim.diagnostics`): how far
its PEN moves the ARAP stage; and its two stages' drape times (``ms_arap``, ``ms_pen``: every run records each
stage of a method's ``timings_ms`` as ``ms_<stage>`` per frame)."""

from drapebench.metric_info import MetricInfo

METRICS = {
    "pen_mm": MetricInfo("PEN (mm)", "mm", "neither: how much GenSim's PEN moves its ARAP stage", "mean |PEN displacement| over vertices and frames"),
    "pen_p99_mm": MetricInfo("PEN p99 (mm)", "mm", "neither", "99th percentile of |PEN displacement| over vertices and frames"),
    "hem_drop_mm": MetricInfo("hem drop (mm)", "mm", "neither: 0 holds, > 0 the skirt falls or stretches", "mean lowering of the hem (lowest boundary loop) by GenSim's PEN"),
    "pin_drop_mm": MetricInfo("pin drop (mm)", "mm", "neither: 0 holds, > 0 the garment falls", "mean lowering of the pinned vertices (waistband) by GenSim's PEN"),
    "ms_arap": MetricInfo("ARAP (ms)", "ms", "lower", "drape time per frame of GenSim's ARAP stage (Alg. 1-2, the handles' body queries included)"),
    "ms_pen": MetricInfo("PEN (ms)", "ms", "lower", "drape time per frame of GenSim's PEN (its geometry encoding included)"),
}  # fmt: skip
