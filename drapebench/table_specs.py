"""One spec per committed table: the experiments and sweep overrides that make its runs, the rows and garments it
shows, its metrics and column groups, and what is printed or drawn with it. ``drapebench.report`` reads the spec
to write a table, ``drapebench.reproduce`` to run and write it, the claims scoreboard to name its command. Adding a
table is one :class:`TableSpec` here (and, if its scene is new, one ``conf/experiment/<name>.yaml``).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Sweep:
    """One ``python run.py -m experiment=<experiment> <overrides>`` (a comma list in an override sweeps it, as in
    Hydra; the experiment's own ``hydra.sweeper.params`` are swept too, an override replacing the key's list)."""

    experiment: str
    overrides: tuple = ()

    def command(self) -> str:
        """The sweep as a shell command line."""
        quoted = [f"'{o}'" if any(c in o for c in "[]()*") else o for o in self.overrides]
        return " ".join(["python run.py -m", f"experiment={self.experiment}", *quoted])


@dataclass(frozen=True)
class TableSpec:
    """A committed table ``reports/<name>``. ``metrics`` (run-record keys; ``<metric>@<variant>`` a method's
    variant of its drape) per column group ``group`` (a run-record key; None: one row per run); ``sweeps`` run in
    order (``sweeps_of``: the runs of another table instead); ``methods`` / ``garments``: the rows in order and the
    garments read (empty: all the runs'); ``note``: printed under the table; ``bars``: metrics also drawn as bars;
    ``pareto``: the runtime plot per garment with each method's speed-up over pbs (else one scatter);
    ``bench``: a script that writes the table itself (argv after ``python``, ``{out}`` the output path) instead of
    sweeps; ``evaluations``: instead a plot of the runs' per-epoch evaluations."""

    name: str
    what: str
    metrics: tuple = ()
    group: str | None = "garment"
    sweeps: tuple = ()
    sweeps_of: str = ""
    methods: tuple = ()
    garments: tuple = ()
    note: str = ""
    bars: tuple = ()
    pareto: bool = False
    bench: tuple = ()
    evaluations: bool = False

    def command(self) -> str:
        """The one command that regenerates the table."""
        return f"python -m drapebench.reproduce --tables {self.name}"


def _untrained(experiment: str, methods, *extra) -> tuple:
    """Sweeps of each method's skinning before training (``<m>_untrained``: ``train.epochs=0``)."""
    return tuple(Sweep(experiment, (f"method={m}", f"method.name={m}_untrained", "train.epochs=0", *extra)) for m in methods)


NO_INEXT_OPTIMUM = ("method=gaps_optimum", "method.name=gaps_no_inext_optimum", "+method.params.inextensibility_weight=0.0",
                    "+method.params.relax_inextensibility_weight=2.0e+8")  # fmt: skip
VAE_METRICS = ("eps_c", "eps_c_canonical", "sampled_prior_pct", "sampled_codes_pct", "vertex_error_mm", "ms_per_frame")
SEEDS = "seed=0,1,2"
ONE_THREAD = "threads=1"

SPECS = {s.name: s for s in [
    TableSpec("baseline", "the lbs zero point on four garments, walking", ("eps_e", "eps_a", "eps_c"),
              sweeps=(Sweep("baseline"),)),
    TableSpec("gaps_table1", "GAPS Table 1: ε_e, ε_a, ε_c of SNUG, NCS and GAPS (before the push-out, and after it), "
              "their untrained skinnings, GAPS's loss optimum, lbs and pbs on four garments, held-out kick",
              ("eps_e", "eps_a", "eps_c", "eps_c@postprocessed"),
              sweeps=(Sweep("gaps_table1", ("method=snug_like,ncs_like,gaps", SEEDS, ONE_THREAD)),
                      Sweep("gaps_table1", ("method=lbs,pbs", ONE_THREAD)),
                      *_untrained("gaps_table1", ("gaps", "ncs_like", "snug_like")),
                      Sweep("gaps_table1", ("method=gaps_optimum", ONE_THREAD))),
              methods=("lbs", "pbs", "snug_like", "snug_like_untrained", "ncs_like", "ncs_like_untrained", "gaps", "gaps_untrained",
                       "gaps_optimum")),  # fmt: skip
    TableSpec("gaps_table2", "GAPS Table 2: ε_c of GAPS, k_ext = 1 and without L_inext, each loss's optimum and GAPS's "
              "untrained skinning (the claims' control)", ("eps_c",),
              sweeps=(Sweep("gaps_table2", (SEEDS, ONE_THREAD)),
                      *_untrained("gaps_table2", ("gaps",)),
                      Sweep("gaps_table2", ("method=gaps_optimum", ONE_THREAD)),
                      Sweep("gaps_table2", ("method=gaps_optimum", "method.name=gaps_kext1_optimum", "+method.params.kext=one", ONE_THREAD)),
                      Sweep("gaps_table2", (*NO_INEXT_OPTIMUM, ONE_THREAD))),
              methods=("gaps", "gaps_kext1", "gaps_no_inext", "gaps_untrained", "gaps_optimum", "gaps_kext1_optimum",
                       "gaps_no_inext_optimum")),  # fmt: skip
    TableSpec("gaps_table3", "GAPS Table 3: ε_e, ε_a of the dress on an average, a heavy and a very heavy body, with and "
              "without L_inext, each loss's optimum and the untrained skinning", ("eps_e", "eps_a", "eps_c"), group="shape",
              sweeps=(Sweep("gaps_table3", (SEEDS, ONE_THREAD)), *_untrained("gaps_table3", ("gaps",)),
                      Sweep("gaps_table3", ("method=gaps_optimum", ONE_THREAD)), Sweep("gaps_table3", (*NO_INEXT_OPTIMUM, ONE_THREAD))),
              methods=("gaps", "gaps_no_inext", "gaps_untrained", "gaps_optimum", "gaps_no_inext_optimum")),  # fmt: skip
    TableSpec("gaps_table4", "GAPS Table 4: training time, time to converge and drape time of Table 1's runs",
              ("train_s", "converged_s", "ms_per_frame"), sweeps_of="gaps_table1", methods=("lbs", "pbs", "snug_like", "ncs_like", "gaps")),
    *[TableSpec(f"gaps_heldout_{g}", f"GAPS against its own skinning, its loss's optimum and vbd on held-out motion and "
                f"shapes: the {g}", ("vertex_error_mm", "vertex_error_mm@untrained", "eps_c", "eps_c@postprocessed", "loss_gap_closed"), group="shape",
                sweeps=(Sweep("gaps_heldout", (SEEDS, "method=gaps", f"garment={g}")), Sweep("gaps_heldout", ("method=lbs,gaps_optimum", f"garment={g}"))),
                methods=("lbs", "gaps_optimum", "gaps"), garments=(g,)) for g in ("tshirt", "dress", "skirt")],  # fmt: skip
    TableSpec("gaps_heldout_tshirt_anny", "gaps_heldout_tshirt on the full anny body",
              ("vertex_error_mm", "vertex_error_mm@untrained", "eps_c", "eps_c@postprocessed", "loss_gap_closed"), group="shape",
              sweeps=(Sweep("gaps_heldout", (SEEDS, "method=gaps", "garment=tshirt", "body=anny")),
                      Sweep("gaps_heldout", ("method=lbs,gaps_optimum", "garment=tshirt", "body=anny"))),
              methods=("lbs", "gaps_optimum", "gaps")),  # fmt: skip
    TableSpec("gaps_generalisation", "GAPS trained on named motions and on random motion against its untrained skinning "
              "and lbs on the held-out kick and on dance", ("eps_e", "eps_a", "eps_c", "vertex_error_mm", "energy_j"), group="scene",
              sweeps=(Sweep("gaps_generalisation", ("method=lbs",)), *_untrained("gaps_generalisation", ("gaps",)),
                      Sweep("gaps_generalisation", ("method=gaps",)),
                      Sweep("gaps_generalisation", ("method=gaps", "method.name=gaps_random", "train.dataset=train_random_small")),
                      Sweep("gaps_generalisation", ("method=pbs_style3d,pbs_half_dt",))),
              methods=("lbs", "gaps_untrained", "gaps", "gaps_random", "pbs_style3d", "pbs_half_dt")),  # fmt: skip
    TableSpec("gensim_table1", "GenSim Table 1 measured: one trained model per method on what it did not see in training",
              ("eps_c", "vertex_error_mm"), group="experiment",
              sweeps=(Sweep("gensim_table1", ("experiment_name=unseen_motion",)),
                      Sweep("gensim_table1", ("experiment_name=unseen_shape", "motion.betas=[1.0,-1.0],[-1.0,1.5]")),
                      Sweep("gensim_table1", ("experiment_name=unseen_garment_kind", "garment=pants", "method=lbs,gensim")),
                      Sweep("gensim_table1", ("experiment_name=unseen_resolution", "+garment.params.resolution=0.012", "method=lbs,gensim")),
                      Sweep("gensim_table1", ("experiment_name=other_body", "body=anny_lowres", "method=lbs,gensim"))),
              note="– : not run, the method trains one model per garment mesh and body (gaps, vae), so this column would "
              "need a new model rather than test the trained one."),  # fmt: skip
    TableSpec("gensim_table2", "GenSim Table 2: unsupervised against supervised (L2 to vbd) GenSim on garment kinds it "
              "never saw, beside lbs, the ARAP stage and the loss's optimum", ("edge_mm", "smoothness", "eps_c", "vertex_error_mm"),
              sweeps=(Sweep("gensim_table2", (SEEDS,)), Sweep("gensim_table2", ("method=gensim_optimum",))),
              methods=("gensim", "gensim_l2", "lbs", "gensim_arap", "gensim_optimum")),  # fmt: skip
    TableSpec("gensim_ablation", "GenSim without its restrain, bending or collision term (Table 2's runs)",
              ("eps_e", "edge_mm", "smoothness", "eps_c", "vertex_error_mm"), sweeps_of="gensim_table2",
              methods=("gensim", "gensim_arap", "gensim_no_restrain", "gensim_no_bending", "gensim_no_collision", "lbs")),  # fmt: skip
    TableSpec("gensim_pen", "GenSim Fig. 2 / 11: what PEN adds to its ARAP stage (energy, ε_c, ε_e, displacement), with "
              "one-step ARAP (nitr = 1) and lbs as controls", ("energy_j", "eps_c", "eps_e", "smoothness", "pen_mm", "pen_p99_mm"),
              sweeps=(Sweep("gensim_pen", (SEEDS, ONE_THREAD)), Sweep("gensim_pen", ("method=lbs,gensim_optimum",)),
                      Sweep("gensim_pen", ("method=gensim_arap", "method.name=gensim_arap_nitr1", "+method.params.arap_steps=1"))),
              methods=("gensim_arap", "gensim_arap_nitr1", "gensim", "gensim_optimum", "lbs")),  # fmt: skip
    TableSpec("gensim_fig10", "GenSim Fig. 10: the loss ablation V1 / V2 / V3 on a short skirt beside the ARAP stage",
              ("hem_drop_mm", "pin_drop_mm", "eps_e", "eps_c", "pen_mm"), sweeps=(Sweep("gensim_fig10", (SEEDS, ONE_THREAD)),), bars=("hem_drop_mm", "eps_e")),
    TableSpec("runtime_vs_error", "every method config on four garments: drape time against error, speed-ups over pbs",
              ("ms_per_frame", "vertex_error_mm", "eps_e", "eps_a", "eps_c", "train_s"),
              sweeps=(Sweep("runtime_vs_error", ("garment=tshirt,skirt,dress,pants",)),), pareto=True),
    TableSpec("stability", "lbs and GAPS at the ends of the shape space, four stress motions, both dtypes: max strain, "
              "deepest penetration, ε_c, drift", ("max_strain", "max_penetration_mm", "eps_c", "drift_mm"), group=None,
              sweeps=(Sweep("stability", ("viz=none",)),
                      Sweep("stability", ("viz=none", "motion=random", "motion.n_frames=10000", "motion.betas=[0.0]", "dtype=float32")))),
    TableSpec("vae_table1", "VTO Table 1: ε_c of the VAE and its two collision ablations beside lbs, gaps and gensim on "
              "unseen motions and shapes, with the canonical garments' and decoded samples' collisions",
              VAE_METRICS, group="case",
              sweeps=(Sweep("vae_table1", ("method=vae,vae_no_selfsup,vae_no_collision", SEEDS, ONE_THREAD)),
                      Sweep("vae_table1", ("method=lbs,gaps,gensim", SEEDS, ONE_THREAD))),
              methods=("lbs", "gaps", "gensim", "vae_no_collision", "vae_no_selfsup", "vae")),  # fmt: skip
    TableSpec("vae_table1_dress", "vae_table1 on the dress", VAE_METRICS, group="case",
              sweeps=(Sweep("vae_table1", ("garment=dress", "method=lbs,vae,vae_no_selfsup,vae_no_collision", SEEDS, ONE_THREAD)),),
              methods=("lbs", "vae_no_collision", "vae_no_selfsup", "vae")),  # fmt: skip
    TableSpec("vae_fig4", "VTO Fig. 4: the VAE variants' collisions per training epoch (a plot)", sweeps_of="vae_table1",
              methods=("vae", "vae_no_selfsup", "vae_no_collision"), evaluations=True),
    TableSpec("vae_table2", "VTO Table 2: the VAE's regressor, decoder and posing time per frame",
              bench=("benchmarks/bench_vae.py", "--out", "{out}")),
    TableSpec("scaling", "drape time and peak memory against garment size and sequence length",
              bench=("benchmarks/bench_scaling.py", "--out", "{out}")),
]}


def spec(name: str) -> TableSpec:
    """The spec of table ``name``; KeyError naming the tables when there is none."""
    if name not in SPECS:
        raise KeyError(f"no table {name!r}; tables: {', '.join(SPECS)}")
    return SPECS[name]


def sweeps(s: TableSpec) -> tuple:
    """The sweeps whose runs table ``s`` reads (its own, or those of ``sweeps_of``)."""
    return spec(s.sweeps_of).sweeps if s.sweeps_of else s.sweeps
