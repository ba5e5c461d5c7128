"""The committed tables of the VAE's experiments (VTO's Table 1, Figs. 3 and 4, Sec. 4.2, Table 2): one
:class:`drapebench.table_specs.TableSpec` each, which ``drapebench.report`` and ``drapebench.reproduce`` find through
:mod:`drapebench.plugins`."""

from drapebench.table_specs import ONE_THREAD, SEEDS, Sweep, TableSpec

VAE_METRICS = ("eps_c", "eps_c_canonical", "sampled_prior_pct", "sampled_codes_pct", "vertex_error_mm", "ms_per_frame")

TABLES = [
    TableSpec("vae_table1", "VTO Table 1: ε_c of the VAE and its two collision ablations beside lbs, gaps and gensim on "
              "unseen motions and shapes, with the canonical garments' and decoded samples' collisions",
              VAE_METRICS, group="case",
              sweeps=(Sweep("vae_table1", ("method=vae,vae_mean_code,vae_no_selfsup,vae_no_collision", SEEDS, ONE_THREAD)),
                      Sweep("vae_table1", ("method=lbs,gaps,gensim", SEEDS, ONE_THREAD))),
              methods=("lbs", "gaps", "gensim", "vae_mean_code", "vae_no_collision", "vae_no_selfsup", "vae"),
              note="Held out: the kick from every method's training; the squat from the VAE's (data=cpu) and GenSim's "
              "(random and walk), not from GAPS's, whose train_gaps holds walk, run, jump, squat, dance and random motion: "
              "its squat cells are not held out."),  # fmt: skip
    TableSpec("vae_table1_dress", "vae_table1 on the dress", VAE_METRICS, group="case",
              sweeps=(Sweep("vae_table1", ("garment=dress", "method=lbs,vae,vae_mean_code,vae_no_selfsup,vae_no_collision", SEEDS, ONE_THREAD)),),
              methods=("lbs", "vae_mean_code", "vae_no_collision", "vae_no_selfsup", "vae")),  # fmt: skip
    TableSpec("vae_sec42", "VTO Sec. 4.2: the test drapes' collisions in the canonical space (decoded) and posed, beside lbs "
              "(vae_table1's runs)", ("eps_c_canonical", "eps_c"), group="case", sweeps_of="vae_table1",
              methods=("lbs", "vae_no_collision", "vae_no_selfsup", "vae")),  # fmt: skip
    TableSpec("vae_sec42_dress", "vae_sec42 on the dress (vae_table1_dress's runs)", ("eps_c_canonical", "eps_c"), group="case",
              sweeps_of="vae_table1_dress", methods=("lbs", "vae_no_collision", "vae_no_selfsup", "vae")),  # fmt: skip
    TableSpec("vae_fig3", "VTO Fig. 3: the training drapes projected to the canonical space by optimisation against inverse "
              "skinning alone (canonical collisions, reprojection error)", bench=("-m", "methods.vae.projection_table", "--out", "{out}")),
    TableSpec("vae_fig4", "VTO Fig. 4: the VAE variants' collisions per training epoch (a plot and its CSV)", sweeps_of="vae_table1",
              methods=("vae", "vae_no_selfsup", "vae_no_collision"), evaluations=True),
    TableSpec("vae_table2", "VTO Table 2: the VAE's regressor, decoder and posing time per frame",
              bench=("benchmarks/bench_vae.py", "--out", "{out}")),
]
