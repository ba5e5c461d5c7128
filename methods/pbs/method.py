"""The Newton reference simulation behind the method interface, so it gets its own row (and runtime) in
every table: nothing is learned; ``drape`` runs (or loads) :func:`drapebench.reference.simulate_record`."""

from __future__ import annotations

from methods.base import DrapeResult, DrapingMethod, FitReport


class PBSMethod(DrapingMethod):
    """Physics-based simulation (Newton VBD or Style3D) of each garment and sequence.

    cfg: ``solver`` ("vbd" default, or "style3d") and any :class:`drapebench.reference.SimSettings`
    field (substeps, iterations, settle_frames, pins, self_contact, device, ...); ``cache`` (default True).
    """

    name = "pbs"
    generic = True
    needs_reference = False

    def __init__(self, cfg=None) -> None:
        super().__init__(cfg)
        from drapebench.reference import SimSettings

        settings = {k: v for k, v in self.cfg.items() if k not in ("solver", "cache")}
        SimSettings.for_solver(self.cfg.get("solver", "vbd"), **settings)  # fail fast on bad settings

    def fit(self, data, train_cfg=None) -> FitReport:
        """Nothing to learn: binds the body and material."""
        self.bind(data.body, data.material)
        return FitReport()

    def drape(self, garment, seq) -> DrapeResult:
        """(T, V, 3) simulated drape. timings_ms["simulate"] is the simulation's own wall time (setup,
        settling and the sequence), the original one when the drape comes from the cache; then
        timings_ms["cache_load"] is the time to load it."""
        from drapebench.reference import simulate_record

        self._require_bound()
        cfg = dict(self.cfg)
        solver, cache = cfg.pop("solver", "vbd"), bool(cfg.pop("cache", True))
        rec = simulate_record(garment, seq, self.body, self.material, solver, cache=cache, **cfg)
        timings = {"simulate": rec.sim_s * 1e3}
        if rec.from_cache:
            timings["cache_load"] = rec.load_s * 1e3
        return DrapeResult(rec.vertices, timings)
