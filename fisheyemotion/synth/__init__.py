"""Ground-truth fisheye road scenes: scenario specs, a ray-casting renderer, sequences on disk."""

from .render import FrameTruth, Renderer, render_frames
from .scenario import Box, Scenario, list_scenarios, load_scenario, parse_scenario
from .write import object_rows, scenario_doc, write_sequence

__all__ = ["Box", "FrameTruth", "Renderer", "Scenario", "list_scenarios", "load_scenario",
           "object_rows", "parse_scenario", "render_frames", "scenario_doc", "write_sequence"]
