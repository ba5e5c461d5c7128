"""The VAE collision model (Santesteban, Thuerey, Otaduy, Casas, CVPR 2021); see ``methods/vae/README.md``."""

from methods.vae.method import VAEModel

__all__ = ["VAEModel"]
