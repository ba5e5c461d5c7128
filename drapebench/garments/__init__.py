"""Parametric garments on the canonical body, user garments, and their validity checks."""

from drapebench.garments.factory import GARMENT_KINDS, garment_from_config, garment_label, garment_params, make_garment
from drapebench.garments.garment import Garment, load_garment
from drapebench.garments.validate import GarmentReport, validate_garment

__all__ = ["GARMENT_KINDS", "Garment", "GarmentReport", "garment_from_config", "garment_label", "garment_params", "load_garment", "make_garment", "validate_garment"]
