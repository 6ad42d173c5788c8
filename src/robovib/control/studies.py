"""Deprecated location: the closed-loop studies live in :mod:`robovib.studies.control_closed_loop`.

Kept only so that ``robovib.cli`` (not yet split into ``cli/``) keeps working; nothing is
imported from :mod:`robovib.sim` until an attribute is asked for. Remove once the CLI imports
the studies package directly.
"""

from __future__ import annotations


def __getattr__(name: str):
    import importlib

    module = importlib.import_module("robovib.studies.control_closed_loop")
    return getattr(module, name)
