"""The diagnostics the VAE reports beside the library's metrics (:meth:`methods.vae.VAEModel.diagnostics`):
collisions in the canonical space, of its decoded garments and of decoded latent samples."""

from drapebench.metric_info import MetricInfo

METRICS = {
    "eps_c_canonical": MetricInfo("ε_c canon. (%)", "%", "lower, 0 ideal",
                                  "decoded canonical garment vertices inside the canonical body (VAE, before posing)"),
    "sampled_prior_pct": MetricInfo("samples N(0,I) (%)", "%", "lower, 0 ideal",
                                    "vertices of decoded latent samples z ~ N(0, I) inside the canonical body (VAE)"),
    "sampled_prior3_pct": MetricInfo("samples N(0,9I) (%)", "%", "lower, 0 ideal",
                                     "vertices of decoded latent samples z ~ N(0, 9 I) inside the canonical body (VAE)"),
    "sampled_codes_pct": MetricInfo("samples codes (%)", "%", "lower, 0 ideal",
                                    "vertices of decoded latent samples at the training codes' spread inside the canonical body (VAE)"),
}  # fmt: skip
