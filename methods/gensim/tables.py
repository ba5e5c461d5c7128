"""The committed tables of GenSim's experiments (its paper's Tables 1-2, Figs. 2, 10, 11, the loss ablation): one
:class:`drapebench.table_specs.TableSpec` each, which ``drapebench.report`` and ``drapebench.reproduce`` find through
:mod:`drapebench.plugins`."""

from drapebench.table_specs import ONE_THREAD, SEEDS, Sweep, TableSpec, untrained

TABLES = [
    TableSpec("gensim_table1", "GenSim Table 1 measured: one trained model per method on what it did not see in training",
              ("eps_c", "vertex_error_mm"), group="experiment",
              sweeps=(Sweep("gensim_table1", ("experiment_name=unseen_motion",)),
                      Sweep("gensim_table1", ("experiment_name=unseen_shape", "motion.betas=[1.0,-1.0],[-1.0,1.5]")),
                      Sweep("gensim_table1", ("experiment_name=unseen_garment_kind", "garment=pants", "method=lbs,gensim")),
                      Sweep("gensim_table1", ("experiment_name=unseen_resolution", "+garment.params.resolution=0.012", "method=lbs,gensim")),
                      Sweep("gensim_table1", ("experiment_name=other_body", "body=anny_lowres", "method=lbs,gensim"))),
              note="– : not run, the method trains one model per garment mesh and body (gaps, vae), so this column would "
              "need a new model rather than test the trained one."),  # fmt: skip
    TableSpec("gensim_table2", "GenSim Table 2 as the paper measured it: unsupervised against supervised (L2 to vbd) GenSim "
              "on held-out instances of the garment kinds it trains on (another size, mesh, motion and body shape), and "
              "unsupervised GenSim trained on the supervised variant's frames (equal data), beside lbs, the ARAP stage and "
              "the loss's optimum", ("edge_mm", "smoothness", "eps_c", "vertex_error_mm"),
              sweeps=(Sweep("gensim_table2", (SEEDS,)),
                      Sweep("gensim_table2", (SEEDS, "method=gensim_l2", "method.name=gensim_on_l2_frames", "method.params.supervised=false")),
                      Sweep("gensim_table2", ("method=gensim_optimum",))),
              methods=("gensim", "gensim_l2", "gensim_on_l2_frames", "lbs", "gensim_arap", "gensim_optimum"),
              note="gensim_on_l2_frames: gensim_l2's configuration (its 144 training frames, those with reference drapes, "
              "and its budget) with the unsupervised losses, so that its row against gensim_l2's differs in the loss alone."),  # fmt: skip
    TableSpec("gensim_generalisation", "GenSim on garment kinds it never saw (pants, shorts, dress): unsupervised against "
              "supervised (L2 to vbd), beside lbs, the ARAP stage and the loss's optimum", ("edge_mm", "smoothness", "eps_c", "vertex_error_mm"),
              sweeps=(Sweep("gensim_generalisation", (SEEDS,)), Sweep("gensim_generalisation", ("method=gensim_optimum",))),
              methods=("gensim", "gensim_l2", "lbs", "gensim_arap", "gensim_optimum")),  # fmt: skip
    TableSpec("gensim_ablation", "GenSim without its restrain, bending or collision term (gensim_generalisation's runs)",
              ("eps_e", "edge_mm", "smoothness", "eps_c", "vertex_error_mm"), sweeps_of="gensim_generalisation",
              methods=("gensim", "gensim_arap", "gensim_no_restrain", "gensim_no_bending", "gensim_no_collision", "lbs")),  # fmt: skip
    TableSpec("gensim_pen", "GenSim Fig. 2 / 11: what PEN adds to its ARAP stage (energy, ε_c, ε_e, displacement), with "
              "one-step ARAP (nitr = 1), PEN untrained and lbs as controls", ("energy_j", "eps_c", "eps_e", "smoothness", "pen_mm", "pen_p99_mm"),
              sweeps=(Sweep("gensim_pen", (SEEDS, ONE_THREAD)), Sweep("gensim_pen", ("method=lbs,gensim_optimum",)),
                      Sweep("gensim_pen", ("method=gensim_arap", "method.name=gensim_arap_nitr1", "method.params.arap_steps=1")),
                      *untrained("gensim_pen", ("gensim",), SEEDS, ONE_THREAD)),
              methods=("gensim_arap", "gensim_arap_nitr1", "gensim_untrained", "gensim", "gensim_optimum", "lbs")),  # fmt: skip
    TableSpec("gensim_fig10", "GenSim Fig. 10: the loss ablation V1 / V2 / V3 on a short skirt beside the ARAP stage",
              ("hem_drop_mm", "pin_drop_mm", "eps_e", "eps_c", "pen_mm"), sweeps=(Sweep("gensim_fig10", (SEEDS, ONE_THREAD)),), bars=("hem_drop_mm", "eps_e"),
              note="The skirt is a short one (garment.params.length 0.25 in conf/experiment/gensim_fig10.yaml), not the "
              "skirt of gensim_pen: their ARAP rows differ."),  # fmt: skip
]
