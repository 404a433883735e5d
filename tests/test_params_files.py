"""The documented ``data/params/no_*.yaml`` files: each turns one default off and nothing else,
and the setting it names refuses bad values with its name (docs/evaluation.md quotes each file)."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import pytest

import fisheyemotion as fm

FOLDER = Path(__file__).resolve().parents[1] / "data" / "params"

#: file: (field, its value in the file, the default, Params.paper()'s or None where the paper
#: pipeline's is not asserted, bad values, the error's start)
CASES = {
    "no_bootstrap.yaml": ("scene_bootstrap", False, True, False, ("yes",),
                          "scene_bootstrap: expected a bool"),
    "no_contact_columns.yaml": ("contact_columns", 0, 3, None, (-1,), "contact_columns"),
    "no_contact_epipolar.yaml": ("contact_epipolar", False, True, None, (), ""),
    "no_epipolar_significance.yaml": ("epipolar_significance", 0.0, 2.0, 0.0, (-1.0,),
                                      "epipolar_significance: expected a finite number"),
    "no_extent.yaml": ("extent_reach", 0.0, 0.5, 0.0, (), ""),
    "no_extent_residual.yaml": ("extent_residual", False, True, None, ("yes",),
                                "extent_residual: expected a bool"),
    "no_photometric_view.yaml": ("photometric_view", False, True, None, (1,),
                                 "photometric_view: expected a bool"),
    "no_region_gap.yaml": ("region_gap", 0, 1, 0, (-1, 1.5, True),
                           "region_gap: expected an integer >= 0"),
    "no_second_pass.yaml": ("second_pass", 0, 2, 0, (-1, 2.0, False),
                            "second_pass: expected an integer >= 0"),
    "no_receding.yaml": ("receding", 0.0, 2.0, 0.0, (-1.0, float("nan"), "a"),
                         "receding: expected a finite number"),
    "no_range_tolerance.yaml": ("photometric_range_error", 0.0, 0.03, None,
                                (-0.01, float("inf"), "a"),
                                "photometric_range_error: expected a finite number"),
    "no_edge_explained.yaml": ("photometric_edge", 0.0, 0.1, None, (-0.1, float("nan"), "a"),
                               "photometric_edge: expected a finite number"),
    "no_two_spans.yaml": ("photometric_span", 0.0, 0.2, None, (-0.1, float("nan"), "a"),
                          "photometric_span: expected a finite number"),
    "no_pixel_carry.yaml": ("carry_share", 0.0, 0.6, 0.0, (-0.1, 1.5, float("nan"), "a"),
                            "carry_share: expected a number in"),
    "no_growth.yaml": ("grow", 0, 4, 0, (-1, 2.0, True), "grow: expected an integer >= 0"),
    "no_road_spill.yaml": ("road_spill", 0.0, 15.0, 0.0, (-1.0, float("nan"), "a"),
                           "road_spill: expected a finite number"),
    "no_confirmation.yaml": ("confirm_reach", 0, 8, 0, (-1, 8.0, True),
                             "confirm_reach: expected an integer >= 0"),
    "no_three_views.yaml": ("range_consistency", 0.0, 1.5, 0.0, (-1.0, float("nan"), "a"),
                            "range_consistency: expected a finite number"),
}


def test_every_documented_off_file_is_tested():
    assert {p.name for p in FOLDER.glob("no_*.yaml")} == set(CASES)


@pytest.mark.parametrize("name", sorted(CASES))
def test_a_documented_file_turns_only_its_setting_off(name):
    field, off_value, default, paper, bad, message = CASES[name]
    off = fm.Params.load(FOLDER / name)
    assert getattr(off, field) == off_value and getattr(fm.Params(), field) == default
    assert type(getattr(off, field)) is type(default)
    assert off.replace(**{field: default}) == fm.Params()
    if paper is not None:
        assert getattr(fm.Params.paper(), field) == paper
    for value in bad:
        with pytest.raises(ValueError, match=message):
            fm.Params(**{field: value})


def test_the_fewer_false_alarms_file_asks_two_seeds_of_anti_parallel_led_regions():
    assert fm.Params.load(FOLDER / "fewer_false_alarms.yaml") == fm.Params(antiparallel_seeds=2)
    assert fm.Params().antiparallel_seeds == 1
    for bad in (0, 1.5, True):
        with pytest.raises(ValueError, match="antiparallel_seeds: expected an integer >= 1"):
            fm.Params(antiparallel_seeds=bad)


def test_the_unconfirmed_file_is_the_defaults_before_confirmation_and_three_views():
    assert fm.Params.load(FOLDER / "unconfirmed.yaml") == fm.Params(confirm_reach=0,
                                                                     range_consistency=0.0)


def test_the_unchecked_three_views_file_lets_every_three_view_raise_count():
    unchecked = fm.Params.load(FOLDER / "three_views_unchecked.yaml")
    assert unchecked == fm.Params(range_consistency_alone=1.5)
    assert unchecked.range_consistency_alone <= unchecked.range_consistency
    assert fm.Params().range_consistency_alone == 3.0
    for bad in (-1.0, float("inf"), "a"):
        with pytest.raises(ValueError, match="range_consistency_alone: expected a finite number"):
            fm.Params(range_consistency_alone=bad)


def test_docs_api_names_every_setting_and_every_params_file():
    """docs/api.md's map of the settings (*Parameters*) names every field of ``Params`` and
    every file of ``data/params``: a setting or a file added without it fails here."""
    text = (FOLDER.parents[1] / "docs" / "api.md").read_text(encoding="utf-8")
    section = text[text.index("## Parameters"):text.index("## The engine alone")]
    named = set(re.findall(r"`([a-z_0-9.]+)", section))
    fields = {f.name for f in dataclasses.fields(fm.Params)}
    assert fields - named == set()
    assert {p.name for p in FOLDER.glob("*.yaml")} - named == set()
