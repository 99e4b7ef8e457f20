"""Nested held-out judgement (core/identification/validation.py): folds, cached fits, choices
re-made per fold, the error band of a length.
"""

import numpy as np
import pytest

from pma_model_ros.core.files.shipped_data import shipped_force_map
from pma_model_ros.core.identification.force_map import ForceMap
from pma_model_ros.core.identification.validation import (
    fold_lengths,
    HeldOut,
    HeldOutBand,
    length_folds,
    select,
)


def map_at(lengths) -> ForceMap:
    """Two points per length, force 100 N at 400 kPa (what the folds see is only the lengths)."""
    lengths = np.repeat(np.asarray(lengths, float), 2)
    return ForceMap(
        np.tile([2e5, 4e5], lengths.size // 2), lengths, np.tile([0.0, 100.0], lengths.size // 2)
    )


def test_a_table_map_is_judged_length_by_length_longest_first():
    fmap = shipped_force_map('DMSP-20-300')
    assert fold_lengths(fmap) == pytest.approx([0.296, 0.282, 0.267, 0.25, 0.237, 0.222])


def test_a_recordings_cells_of_one_held_length_are_one_fold():
    """Five held lengths, each recorded in cells 0.5 mm apart (as fit --bag averages them): five
    folds, whose lengths are their cells' mean.
    """
    held = [0.198, 0.211, 0.224, 0.237, 0.250]
    cells = [h + d for h in held for d in (-0.0005, 0.0, 0.0005)]
    folds = length_folds(map_at(cells))
    assert len(folds) == 5
    assert fold_lengths(map_at(cells)) == pytest.approx(held[::-1])


def test_lengths_that_never_hold_still_are_cut_into_eight_bands():
    lengths = np.linspace(0.2, 0.25, 60)  # 0.85 mm apart: no gap tells held lengths apart
    folds = length_folds(map_at(lengths))
    assert len(folds) == 8 and sum(int(f.sum()) for f in folds) == 120
    assert all(f.sum() in (14, 16) for f in folds)  # 60 lengths of 2 points in 8 bands


def test_nested_choice_is_made_again_without_each_fold():
    """Two constant 'fits' on four lengths: A predicts 100 N, B 90 N, whatever they are fitted
    on; the measured force is 100 N but 80 N at the longest length.  Without a fold, each
    candidate's worst error on the other folds picks the model of that fold, by hand.
    """
    lengths = np.repeat([0.25, 0.24, 0.23, 0.21], 3)
    fmap = ForceMap(np.full(12, 4e5), lengths, np.where(lengths == 0.25, 80.0, 100.0))

    class Constant:
        def __init__(self, value):
            self.value = value

        def force(self, pressure, length):
            return np.full(np.shape(pressure), self.value)

    held = HeldOut(fmap, lambda train: {'A': Constant(100.0), 'B': Constant(90.0)})
    # leave-one-length-out: A errs 20 % (of 100 N) at 0.25 m and 0 elsewhere; B 10 % everywhere
    assert held.errors('A') == pytest.approx([20, 0, 0, 0])
    assert held.errors('B') == pytest.approx([10, 10, 10, 10])
    chosen, nested, per_fold = select({'A': (held, 'A'), 'B': (held, 'B')})
    assert chosen == 'B'  # worst 10 % against 20 %
    # without 0.25 m, A errs 0 % on the rest and is chosen, then errs 20 % at 0.25 m; without any
    # other length, A's 20 % at 0.25 m loses to B's 10 %
    assert per_fold == ['A', 'B', 'B', 'B'] and nested == pytest.approx([20, 10, 10, 10])
    assert len(held._fits) == 10  # 4 singles and 6 pairs (no whole-map fit): each fitted once


def test_the_band_at_a_length():
    """Between the shortest and longest held-out length the worst err of those between them (an
    interpolation's figure); beyond them the worse of those two (an extrapolation's), said so.
    """
    band = HeldOutBand((0.25, 0.234, 0.219), (8.0, 3.0, 1.0), 500.0)
    assert band.at(0.234) == (3.0, True)  # a held-out length: the interior figure
    assert band.at(0.24) == (3.0, True)  # between the longest two: still interpolation
    assert band.at(0.219) == (3.0, True) and band.at(0.25) == (3.0, True)
    assert band.at(0.26) == (8.0, False) and band.at(0.2) == (8.0, False)  # beyond: max(8, 1)
    assert band.values_at(0.24) == {
        'expected error [N]': '15',  # 3 % of 500 N
        'expected error [% of max force]': '3',
    }
    assert band.values_at(0.2) == {
        'expected error [N]': '40',  # 8 % of 500 N
        'expected error [% of max force]': (
            '8 (0.2 m is beyond the measured lengths 0.219..0.25 m: the worst of the shortest and '
            'longest, extrapolated or held there as served)'
        ),
    }
    with pytest.raises(ValueError, match='as many finite lengths as errors'):
        HeldOutBand((0.25,), (1.0, 2.0), 500.0)


def test_two_lengths_have_no_interior_figure():
    band = HeldOutBand((0.25, 0.219), (8.0, 1.0), 500.0)
    assert band.at(0.23) == (8.0, True) and band.at(0.2) == (8.0, False)


def test_a_length_that_measured_no_force_is_judged_by_the_maps_worst():
    """A held-out err of 0: every force measured there was 0 and the clipped model says slack;
    that is no band of 0 N around a prediction, so where every length inside measured no force,
    the map's worst held-out err stands in.
    """
    band = HeldOutBand((0.25, 0.234, 0.219), (8.0, 3.0, 0.0), 500.0)
    assert band.at(0.219) == (3.0, True) and not band.slack_at(0.219)  # the interior: 3
    band = HeldOutBand((0.25, 0.24, 0.23, 0.22), (8.0, 0.0, 0.0, 5.0), 500.0)
    assert band.at(0.235) == (8.0, True) and band.slack_at(0.235)
    assert band.at(0.2) == (8.0, False) and not band.slack_at(0.2)
    assert band.values_at(0.235)['expected error [N]'] == '40'  # 8 % of 500 N
