"""Region confirmation by the frame before (``Params.confirm_reach``, fisheyemotion.confirm)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import fisheyemotion as fm
from fisheyemotion.confirm import confirmed_regions
from fisheyemotion.segment import segment_cells


def _regions(rng, rows, cols, share):
    values = np.where(rng.random((rows, cols)) < share, 1.0, 0.0)
    _, regions, labels = segment_cells(values, threshold=0.5, grid=1, min_area=0,
                                       with_labels=True)
    return regions, labels


@given(st.integers(1, 30), st.integers(1, 30), st.sampled_from([0.02, 0.1, 0.3]),
       st.sampled_from([0.0, 0.01, 0.05]), st.integers(0, 5), st.integers(0, 2**31 - 1))
@settings(max_examples=200, deadline=None)
def test_a_region_is_kept_when_a_cell_of_the_frame_before_is_within_reach(rows, cols, share,
                                                                          before_share, reach,
                                                                          seed):
    """Against a brute-force reference: a region is kept iff one of its cells is within
    ``reach`` (Chebyshev distance) of a cell of ``before``; the kept ones keep their order and
    are labelled 1..m."""
    rng = np.random.default_rng(seed)
    regions, labels = _regions(rng, rows, cols, share)
    before = rng.random((rows, cols)) < before_share
    got_labels, got = confirmed_regions(labels, regions, before, reach)
    br, bc = np.nonzero(before)
    expected = []
    for r in regions:
        rr, cc = np.nonzero(labels == r.label)
        if len(br) and (np.maximum(np.abs(rr[:, None] - br), np.abs(cc[:, None] - bc))
                        <= reach).any():
            expected.append(r)
    assert [r.bbox for r in got] == [r.bbox for r in expected]
    assert [r.label for r in got] == list(range(1, len(expected) + 1))
    want = np.zeros_like(labels)
    for i, r in enumerate(expected, start=1):
        want[labels == r.label] = i
    np.testing.assert_array_equal(got_labels, want)


def test_nothing_before_reports_everything_and_a_wrong_shape_is_named():
    regions, labels = _regions(np.random.default_rng(0), 12, 16, 0.2)
    got_labels, got = confirmed_regions(labels, regions, None, 2)
    assert got == regions
    np.testing.assert_array_equal(got_labels, labels)
    with pytest.raises(ValueError, match="before"):
        confirmed_regions(labels, regions, np.zeros((3, 3), bool), 2)


def test_params_check_confirm_reach():
    for bad in (-1, 1.5, True):
        with pytest.raises(ValueError, match="confirm_reach: expected an integer >= 0"):
            fm.Params(confirm_reach=bad)


# Identity poses put the camera on the default road z = 0: the warning is right, and not what
# this test is about.
@pytest.mark.filterwarnings("ignore:road. the camera is:UserWarning")
def test_a_stream_reports_a_region_once_the_frame_before_had_one_near_it():
    """A sideways flow in a box (inconsistent with the forward motion) is a region. The
    stream's first result reports it; a box that appears far from the last result's is not
    reported until the next result confirms it, though the pose step still sees it
    (``cell_mask``); a single pair is never filtered; ``reset`` forgets the last result."""
    cam = fm.calib.KannalaBrandt(fx=40, fy=40, cx=31.5, cy=23.5, width=64, height=48)
    params = fm.Params.paper(grid=4, min_area=0, threshold=1e-4, confirm_reach=2)
    det = fm.MotionDetector(cam, params=params)
    pose0, pose1 = np.eye(4), np.eye(4)
    pose1[2, 3] = 0.2

    def box(u0, v0):
        flow = np.zeros((48, 64, 2), np.float32)
        flow[v0:v0 + 8, u0:u0 + 8, 0] = 3.0
        return flow

    left, right = box(8, 8), box(44, 28)
    first = det.detect_flow(left, pose0, pose1, stream=True)
    assert first.mask[8:16, 8:16].any()                      # nothing before: reported
    moved = det.detect_flow(right, pose0, pose1, stream=True)
    assert not moved.mask.any() and not moved.regions       # far from the last result's
    assert moved.cell_mask[28:36, 44:52].any()               # ... which the pose step still sees
    again = det.detect_flow(right, pose0, pose1, stream=True)
    assert again.mask[28:36, 44:52].any() and len(again.regions) == 1
    assert det.detect_flow(left, pose0, pose1).mask.any()    # a single pair is not confirmed
    det.reset()
    assert det.detect_flow(right, pose0, pose1, stream=True).mask.any()
