"""``fisheyemotion eval``, ``compare`` and ``demo``: registered into the core CLI by entry point."""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    """Add this package's commands to the ``fisheyemotion`` parser."""
