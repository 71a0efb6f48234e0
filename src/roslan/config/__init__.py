"""Configuration: YAML -> pydantic models, validated once at the edge."""

from __future__ import annotations

from roslan.config.base import Pose, StrictModel, Vec3, format_validation_error, load_yaml_model

__all__ = ["Pose", "StrictModel", "Vec3", "format_validation_error", "load_yaml_model"]
