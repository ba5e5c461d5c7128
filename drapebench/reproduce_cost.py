"""What regenerating tables costs, before anything runs (``python -m drapebench.reproduce --dry-run`` prints it):
per method, its runs and the distinct trainings they need (each training's time: the README's budget table).

A training is identified as a checkpoint is (``drapebench.experiment``): the method's config, the training budget and
data, the body, the material, the seed, and the garment unless the method is generic (one model for any garment);
a method that learns nothing (``learns`` False) or a run with ``train.epochs=0`` needs none. The trainings already
in the checkpoint cache are counted apart (:func:`cached`, which builds each training's scene for its content hash):
the trainings not cached are what is left to train, the runs themselves then only drape and score. A checkpoint
is keyed by configuration; one trained by code of the method that has changed since is trained again by the run, so
it counts as not cached.
"""

from __future__ import annotations

from collections import defaultdict

UNKEYED = ("motion", "dtype", "viz", "chunk_frames")  # override keys (prefixes) that no training depends on


def training_identity(cfg, methods: dict | None = None) -> tuple | None:
    """The identity of the training a composed run config ``cfg`` needs, or None when it trains nothing (a method
    that does not learn, or ``train.epochs`` 0 unless the method fits on reference drapes: it reads them and fits its
    fixed parts even then); ``methods`` (method config -> method object) saves constructing a method per run."""
    from omegaconf import OmegaConf

    from drapebench.experiment import keyed_method_config, method_class

    methods = {} if methods is None else methods
    key = repr(OmegaConf.to_container(cfg.method, resolve=True))
    if key not in methods:
        methods[key] = method_class(cfg)(OmegaConf.to_container(cfg.method.params, resolve=True))
    method = methods[key]
    if not method.learns or (cfg.train.epochs == 0 and not method.needs_reference):
        return None
    plain = lambda node: repr(OmegaConf.to_container(node, resolve=True))  # noqa: E731
    return (cfg.method.name, repr(keyed_method_config(method, cfg)), plain(cfg.train), plain(cfg.data) if method.needs_reference else "",
            cfg.body.name, plain(cfg.material), int(cfg.seed), "" if method.generic else plain(cfg.garment))  # fmt: skip


def _composed(jobs: list):
    """(job, its composed run config, None) for each of ``jobs``, composing once per set of runs that differ only in
    keys no training depends on (:data:`UNKEYED`), in the jobs' order; (job, None, the error) for one whose overrides
    do not compose (its run reports the error)."""
    from hydra import compose, initialize_config_dir

    from drapebench.cache import PROJECT_ROOT
    from drapebench.schema import register

    register()
    configs = {}
    with initialize_config_dir(config_dir=str(PROJECT_ROOT / "conf"), version_base="1.3"):
        for job in jobs:
            key = (job.sweep.experiment, tuple(o for o in job.overrides if not o.lstrip("+").startswith(UNKEYED)))
            if key not in configs:
                try:
                    configs[key] = compose("config", overrides=[f"experiment={key[0]}", *key[1]])
                except Exception as e:  # noqa: BLE001 - any composition error: that run's own to report
                    configs[key] = e
            cfg = configs[key]
            yield (job, None, cfg) if isinstance(cfg, Exception) else (job, cfg, None)


class Group(list):
    """Runs (:class:`drapebench.reproduce.Job`) that must run one after another; ``after``: a run of another group
    that must have ended before this group starts (None: it may start at once)."""

    after = None


def groups(jobs: list) -> list:
    """``jobs`` (:class:`drapebench.reproduce.Job`) in :class:`Group` s that must run one after another, in the order
    of each group's first job: the runs of a method trained on reference drapes (``needs_reference``) by the
    reference set they build (data preset, garment, body) and their seed, the others by the training they load
    (:func:`training_identity`); a run that trains nothing, or whose training is in the checkpoint cache already (it
    only loads it), is a group of its own. A reference set's later groups wait for its first group's first run
    (``after``), which simulates the set and builds what the method derives from it (a projection of the drapes,
    say), so that no set is simulated twice; variants of one seed share a group, as they may share a model (a
    common first stage). Run at once, two groups never train one model twice."""
    return grouped(jobs)[0]


def grouped(jobs: list) -> tuple[list, set, dict]:
    """:func:`groups` of ``jobs``, the set of the jobs (their folders) that train a model: the first run of each
    training not in the checkpoint cache (the others of its group load it), for an estimate of the time left, and
    {folder: error} of the jobs that could not be planned (their overrides do not compose, their method refuses its
    parameters, their scene cannot be built): each is a group of its own, and its run reports the error."""
    out, methods, scenes, trains, seen, unplanned, leaders = {}, {}, {}, set(), set(), {}, {}
    for k, (job, cfg, error) in enumerate(_composed(jobs)):
        try:
            identity = None if cfg is None else _group_identity(cfg, methods, scenes)
        except Exception as e:  # noqa: BLE001 - a refused parameter or a bad scene: that run's own to report
            identity, error = None, e
        if error is not None:
            unplanned[job.dir] = _said(error)
        if identity is not None and identity[1] not in seen:
            seen.add(identity[1])
            trains.add(job.dir)
        key = ("run", k) if identity is None else identity[0]
        if key not in out:
            out[key] = Group()
            if key[0] == "reference set":  # a set's later groups wait for the first run of its first group
                leader = leaders.setdefault(key[:4], job)
                out[key].after = None if leader is job else leader
        out[key].append(job)
    return list(out.values()), trains, unplanned


def _group_identity(cfg, methods: dict, scenes: dict) -> tuple | None:
    """(the group key, the training's identity) of the composed run config ``cfg`` (:func:`groups`), None when it
    trains nothing or only loads a cached model."""
    from omegaconf import OmegaConf

    from drapebench.experiment import method_class

    identity = training_identity(cfg, methods)
    if identity is None or _sealed(cfg, scenes):
        return None
    if method_class(cfg).needs_reference:
        return ("reference set", repr(OmegaConf.to_container(cfg.data, resolve=True)), repr(OmegaConf.to_container(cfg.garment, resolve=True)),
                cfg.body.name, int(cfg.seed)), identity  # fmt: skip
    return identity, identity


def tally(jobs: list) -> tuple[dict, dict]:
    """Per method name (in the order the runs first name it): ``{"runs": n, "trainings": {identity: a composed run
    config that needs it}}`` over ``jobs`` (:class:`drapebench.reproduce.Job`), each composed as its run composes it;
    and {job: error} of those that could not be planned (:func:`grouped`)."""
    out, methods, unplanned = defaultdict(lambda: {"runs": 0, "trainings": {}}), {}, {}
    for job, cfg, error in _composed(jobs):
        try:
            identity = None if cfg is None else training_identity(cfg, methods)
        except Exception as e:  # noqa: BLE001 - a refused parameter: that run's own to report
            error = e
        if error is not None:
            unplanned[job] = _said(error)
            continue
        row = out[cfg.method.name]
        row["runs"] += 1
        if identity is not None:
            row["trainings"].setdefault(identity, cfg)
    return dict(out), unplanned


def _said(error: Exception) -> str:
    """An error in one line: its type and its message's first line."""
    return f"{type(error).__name__}: {(str(error).splitlines() or [''])[0]}"


def _sealed(cfg, scenes: dict) -> bool:
    """Whether the training the composed run config ``cfg`` needs has a checkpoint the run itself would load
    (:func:`drapebench.experiment.loadable_checkpoint` at :func:`drapebench.experiment.checkpoint_path`: sealed, and
    not trained by since-changed code); ``scenes`` (scene key -> scene) builds each distinct scene once."""
    from omegaconf import OmegaConf

    from drapebench.experiment import checkpoint_path, loadable_checkpoint, method_class, method_impl

    scene = _scene(cfg, scenes)
    method = method_class(cfg)(OmegaConf.to_container(cfg.method.params, resolve=True))
    return loadable_checkpoint(checkpoint_path(method, cfg, scene.garment, scene.body), method_impl(cfg))


def _scene(cfg, scenes: dict):
    """The run's scene (:class:`drapebench.scene.Scene`) of the composed run config ``cfg``, built once per distinct
    body, garment, motion and dtype in ``scenes``."""
    from omegaconf import OmegaConf

    from drapebench.scene import Scene

    key = repr([OmegaConf.to_container(cfg[k], resolve=True) for k in ("body", "garment", "motion")] + [str(cfg.dtype)])
    if key not in scenes:
        scenes[key] = Scene.from_config(cfg, device="cpu")
    return scenes[key]


def reference_sets(configs, scenes: dict) -> list:
    """Lines: per distinct reference set (data preset, garment, body, material) that the trainings of the composed run
    configs ``configs`` (of methods trained on reference drapes, not cached) build, how many of its sequences the
    reference cache lacks and their frames, settling included: each is simulated before the training (1-3 s a
    frame on a core: the physics reference run as a method in ``reports/runtime_vs_error.md``). Simulates nothing."""
    from omegaconf import OmegaConf

    from drapebench.data.reference_set import collect_reference_set
    from drapebench.data.reference_spec import ReferenceSetSpec
    from drapebench.reference.settings import SimSettings

    lines, seen = [], set()
    for cfg in configs:
        key = repr([OmegaConf.to_container(cfg[k], resolve=True) for k in ("data", "garment", "body", "material")])
        if key in seen:
            continue
        seen.add(key)
        try:
            scene = _scene(cfg, scenes)
        except Exception as e:  # noqa: BLE001 - its runs report it
            lines.append(f"reference set data={cfg.data.name} on garment {cfg.garment.name}: its scene cannot be built ({_said(e)}): its runs will say why")
            continue
        spec = ReferenceSetSpec.from_config(OmegaConf.to_container(cfg.data, resolve=True))
        found, missing = collect_reference_set(scene.garment, scene.body, scene.material, spec)
        settle = SimSettings.for_solver(spec.solver, **spec.settings).settle_frames  # simulated before each sequence
        frames = sum(seq.n_frames + settle for seq in missing)
        lines.append(f"reference set data={cfg.data.name} on the {scene.garment.name}: {len(missing)} of {len(found.planned)} sequences to "
                     f"simulate, {frames:,} frames (about {frames / 60:.0f}-{frames * 3 / 60:.0f} core-minutes, before its trainings)")  # fmt: skip
    return lines


def cached(configs, scenes: dict | None = None, errors: list | None = None) -> list:
    """Per composed run config of ``configs``, whether the training it needs has a sealed checkpoint in the cache
    (:func:`_sealed`; False where its scene cannot be built, its error appended to ``errors``: its run reports
    it); ``scenes`` as there."""
    scenes = {} if scenes is None else scenes
    out = []
    for cfg in configs:
        try:
            out.append(_sealed(cfg, scenes))
        except Exception as e:  # noqa: BLE001 - that run's own to report
            out.append(False)
            if errors is not None:
                errors.append(f"{cfg.method.name} on garment {cfg.garment.name} ({_said(e)})")
    return out


def summary(jobs: list) -> list:
    """Lines: per method (that has runs) its runs, the distinct trainings they need and how many of those are
    cached already, then the totals, then the reference sets the uncached trainings of methods trained on reference
    drapes build first (:func:`reference_sets`)."""
    from drapebench.experiment import method_class

    (counts, unplanned), scenes, unbuilt = tally(jobs), {}, []
    sealed = {name: cached(row["trainings"].values(), scenes, unbuilt) for name, row in counts.items()}
    lines = [f"{'method':<24}{'runs':>6}{'trainings':>11}{'cached':>8}"]
    lines += [f"{name:<24}{row['runs']:>6}{len(row['trainings']):>11}{sum(sealed[name]):>8}" for name, row in counts.items()]
    lines.append(f"{'all':<24}{sum(r['runs'] for r in counts.values()):>6}{sum(len(r['trainings']) for r in counts.values()):>11}"
                 f"{sum(map(sum, sealed.values())):>8}")
    to_build = [cfg for name, row in counts.items() for cfg, done in zip(row["trainings"].values(), sealed[name])
                if not done and method_class(cfg).needs_reference]  # fmt: skip
    lines += [f"could not plan {job.sweep.experiment} {' '.join(job.overrides)} ({why}): its run will say why" for job, why in unplanned.items()]
    lines += [f"could not build the scene of the training of {what}: its runs will say why" for what in unbuilt]
    return lines + reference_sets(to_build, scenes)
