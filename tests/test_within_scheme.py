"""``resample="within"`` keeps the layouts and resamples episodes inside each one only (an
interval for this suite, not for the population of its layouts): where every layout's episodes
agree, nothing varies within a layout, so every replicate is the point estimate, however far
the layouts differ. The layout-resampling schemes vary with the layouts. (The statistics
module's mutation run left this scheme's layout draw untested: ``scheme != "within"`` mutated
to always draw layouts survived.)"""

from __future__ import annotations

import pytest

from evaluation.stats.clustered import layout_mean_interval, layout_rate_interval

# two layouts that disagree completely, each agreeing with itself
CLUSTERS = [[True] * 4, [False] * 4, [True] * 4, [False] * 4]


def test_within_layouts_of_constant_outcomes_the_interval_is_the_point() -> None:
    assert layout_rate_interval(CLUSTERS, resample="within") == (0.5, 0.5, 0.5)
    assert layout_mean_interval([[1.0, 1.0], [3.0, 3.0]], resample="within") == (2.0, 2.0, 2.0)


@pytest.mark.parametrize("resample", ["layouts", "layouts+within"])
def test_resampling_layouts_varies_with_them(resample: str) -> None:
    rate, low, high = layout_rate_interval(CLUSTERS, resample=resample)
    assert rate == 0.5 and low < 0.5 < high


def test_within_varies_with_the_episodes_of_a_layout() -> None:
    rate, low, high = layout_rate_interval([[True, False] * 10, [True] * 20], resample="within")
    assert rate == 0.75 and low < 0.75 < high
