"""One spec per committed table: the experiments and sweep overrides that make its runs, the rows and garments it
shows, its metrics and column groups, and what is printed or drawn with it. ``drapebench.report`` reads the spec
to write a table, ``drapebench.reproduce`` to run and write it, the claims scoreboard to name its command. A
method's tables live beside its code (``methods/<name>/tables.py``, :func:`specs`); adding one is one
:class:`TableSpec` there (and, if its scene is new, one ``conf/experiment/<name>.yaml``).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Sweep:
    """One ``python run.py -m experiment=<experiment> <overrides>`` (a comma list in an override sweeps it, as in
    Hydra; the experiment's own ``hydra.sweeper.params`` are swept too, an override replacing the key's list),
    less the runs of a method that trains on reference drapes on a garment outside ``reference_garments`` (each
    garment such a method meets costs a reference set and its training)."""

    experiment: str
    overrides: tuple = ()
    reference_garments: tuple = ()  # the garments a method trained on reference drapes (needs_reference) runs on; empty: all

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
    ``pareto``: the runtime plot per garment with each method's speed-up over the reference row (else one scatter);
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


def untrained(experiment: str, methods, *extra) -> tuple:
    """Sweeps of each method's skinning before training (``<m>_untrained``: ``train.epochs=0``)."""
    return tuple(Sweep(experiment, (f"method={m}", f"method.name={m}_untrained", "train.epochs=0", *extra)) for m in methods)


SEEDS = "seed=0,1,2"
ONE_THREAD = "threads=1"

# The tables of no one method: every method config's runtime and error, stability, scaling.
TABLES = [
    TableSpec("runtime_vs_error", "every method and control (the ablations aside: their own tables hold them) on the "
              "garments its own tables train: drape time against error and against the physical energy (StVK + bending + "
              "gravity, what the self-supervised losses minimise besides their collision terms), the ARAP and PEN stage times, speed-ups "
              "over the physics reference run as a method",
              ("ms_per_frame", "vertex_error_mm", "eps_e", "eps_a", "eps_c", "energy_j", "train_s", "ms_arap", "ms_pen"),
              sweeps=(Sweep("runtime_vs_error", ("garment=tshirt,skirt,dress",), reference_garments=("tshirt", "dress")),), pareto=True),
    TableSpec("stability", "the stability experiment's methods at the ends of the shape space, four stress motions, "
              "both dtypes: max strain, deepest penetration, ε_c, drift", ("max_strain", "max_penetration_mm", "eps_c", "drift_mm"), group=None,
              sweeps=(Sweep("stability", ("viz=none",)),
                      Sweep("stability", ("viz=none", "motion=random", "motion.n_frames=10000", "motion.betas=[0.0]", "dtype=float32")))),
    TableSpec("scaling", "drape time and peak memory against garment size and sequence length",
              bench=("benchmarks/bench_scaling.py", "--out", "{out}")),
]


def specs() -> dict[str, TableSpec]:
    """{name: spec} of every committed table: each registered method's (its package's ``tables.TABLES``,
    :mod:`drapebench.plugins`), then :data:`TABLES`; ValueError naming a table two specs share."""
    from drapebench.plugins import declared

    out: dict[str, TableSpec] = {}
    for s in [t for _, tables in declared("tables", "TABLES") for t in tables] + TABLES:
        if s.name in out:
            raise ValueError(f"table {s.name!r} declared twice")
        out[s.name] = s
    return out


def owner(name: str) -> str | None:
    """The implementation folder (``methods/<folder>``) of the method package that declares table ``name`` (its
    ``tables.py``; a ``_gpu`` twin is its CPU table's), or None for the suite's own tables: the code behind a table
    whose rows are not named by methods (a benchmark's rows are garments)."""
    from drapebench.plugins import declared

    base = name.removesuffix("_gpu")
    return next((package.rpartition(".")[2] for package, tables in declared("tables", "TABLES")
                 if any(t.name == base for t in tables)), None)  # fmt: skip


def spec(name: str) -> TableSpec:
    """The spec of table ``name``; KeyError naming the tables when there is none."""
    found = specs()
    if name not in found:
        raise KeyError(f"no table {name!r}; tables: {', '.join(sorted(found))}")
    return found[name]


def sweeps(s: TableSpec) -> tuple:
    """The sweeps whose runs table ``s`` reads (its own, or those of ``sweeps_of``)."""
    return spec(s.sweeps_of).sweeps if s.sweeps_of else s.sweeps
