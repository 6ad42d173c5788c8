"""Compatibility name: atomic outputs live in :mod:`robovib.io.safe_write` (one place)."""

from __future__ import annotations

from .safe_write import atomic_output as atomic_path

__all__ = ["atomic_path"]
