"""Ground-truth fisheye road scenes: scenario specs, a ray-casting renderer, sequences on disk."""

from .render import FrameTruth, Renderer, render_frames
from .scenario import Box, Scenario, list_scenarios, load_scenario, parse_scenario

__all__ = ["Box", "FrameTruth", "Renderer", "Scenario", "list_scenarios", "load_scenario",
           "parse_scenario", "render_frames"]
