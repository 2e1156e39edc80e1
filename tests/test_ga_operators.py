"""Edge cases of the paper GA's MATLAB operators (``ema_bench_solvers.ga_operators``), each
against a value worked out by hand: the boundaries of the settings' checks, the error texts,
integer input, ties, exact bound hits and the round-off guards.  The ordinary cases are in
``test_paper_ga.py``; these are the ones a one-character change in the operators gets past
(found by mutation testing, docs/mutation-testing.md).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from ema_bench_solvers.ga_operators import (
    active_bound_directions,
    adaptive_feasible_mutation,
    heuristic_crossover,
    mads_basis,
    max_feasible_length,
    offspring_counts,
    rank_scaling,
    stalled,
    stochastic_uniform,
)


# --- population split ---------------------------------------------------------------------
def test_counts_at_the_edges_of_their_ranges():
    assert offspring_counts(1) == (1, 0, 0)                          # ceil(0.05) = 1 elite
    assert offspring_counts(10, crossover_fraction=0.0) == (1, 0, 9)
    assert offspring_counts(10, crossover_fraction=1.0) == (1, 9, 0)
    assert offspring_counts(10, elite_count=0) == (0, 8, 2)          # round(0.8 * 10) = 8
    assert offspring_counts(10, elite_count=10) == (10, 0, 0)


@pytest.mark.parametrize("kwargs, message", [
    ({"pop_size": 0}, r"population size must be positive, got 0"),
    ({"pop_size": 10, "crossover_fraction": -0.1},
     r"crossover fraction must lie in \[0, 1\], got -0\.1"),
    ({"pop_size": 10, "elite_count": -1}, r"elite count must lie in \[0, 10\], got -1"),
])
def test_counts_name_the_bad_setting(kwargs, message):
    with pytest.raises(ValueError, match=f"^{message}$"):
        offspring_counts(**kwargs)


# --- rank scaling -------------------------------------------------------------------------
def test_rank_scaling_of_integer_scores():
    raw = np.array([1 / math.sqrt(3), 1.0, 1 / math.sqrt(2)])
    np.testing.assert_allclose(rank_scaling(np.array([3, 1, 2]), 6), 6 * raw / raw.sum())


def test_rank_scaling_breaks_long_runs_of_ties_in_index_order():
    # MATLAB's sort is stable: among equal scores the earlier individual ranks first, however
    # many there are (numpy's default sort keeps that order only for short arrays)
    scores = np.random.default_rng(0).integers(0, 3, 200).astype(float)
    e = rank_scaling(scores, 200)
    rank = np.empty(200)
    rank[np.lexsort((np.arange(200), scores))] = np.arange(1, 201)
    raw = 1 / np.sqrt(rank)
    np.testing.assert_allclose(e, 200 * raw / raw.sum())


# --- stochastic uniform selection ---------------------------------------------------------
def test_stochastic_uniform_small_and_empty_selections():
    e = np.array([1.5, 0.5, 1.0, 1.0])
    np.testing.assert_array_equal(stochastic_uniform(e, 1, start=2.5), [2])  # step 4
    none = stochastic_uniform(e, 0)
    assert none.shape == (0,) and none.dtype == np.intp
    # a zero expectation is allowed (never picked), and so is a total below 1
    np.testing.assert_array_equal(stochastic_uniform([1.0, 0.0, 1.0], 2, start=0.5), [0, 2])
    np.testing.assert_array_equal(stochastic_uniform([0.3, 0.6], 3, start=0.1), [0, 1, 1])


@pytest.mark.parametrize("e", [[1.0, -0.5, 1.0], [0.0, 0.0]])
def test_stochastic_uniform_rejects_negative_or_empty_wheels(e):
    with pytest.raises(ValueError,
                       match="^expectations must be non-negative with a positive sum$"):
        stochastic_uniform(e, 2, rng=np.random.default_rng(0))


def test_stochastic_uniform_needs_a_start_and_names_a_bad_one():
    with pytest.raises(ValueError, match="^give a random generator or a start offset$"):
        stochastic_uniform([1.0, 1.0], 2)
    with pytest.raises(ValueError, match=r"^start must lie in \[0, 1\.0\), got 1\.0$"):
        stochastic_uniform([1.0, 1.0], 2, start=1.0)


def test_stochastic_uniform_random_start_covers_the_whole_step():
    # wheel [0, 1) [1, 2) [2, 3) [3, 4), two pointers 2 apart: start in [0, 1) picks (0, 2),
    # start in [1, 2) picks (1, 3); a uniform start over [0, step) = [0, 2) gives both
    rng = np.random.default_rng(5)
    picks = {tuple(stochastic_uniform(np.ones(4), 2, rng=rng)) for _ in range(40)}
    assert picks == {(0, 2), (1, 3)}


def test_stochastic_uniform_last_pointer_rounded_onto_the_end_of_the_wheel():
    # wheel [0, 0.6) [0.6, 0.7) [0.7, 1.6); step 0.4; the largest start below it puts the last
    # pointer at 1.6 after rounding, the end of the wheel: it belongs to the last individual
    start = np.nextafter(0.4, 0.0)
    np.testing.assert_array_equal(stochastic_uniform([0.6, 0.1, 0.9], 4, start=start),
                                  [0, 2, 2, 2])


# --- heuristic crossover ------------------------------------------------------------------
def test_heuristic_crossover_child_exactly_on_a_bound_is_kept():
    # 0.75 + 1.2 (0.125 - 0.75) = 0 and 0.25 + 1.2 (0.875 - 0.25) = 1, exactly: feasible, so
    # the fallback (alpha = 0.5 would give the midpoints) must not touch them
    worse = np.array([0.75, 0.25, 0.5])
    better = np.array([0.125, 0.875, 0.5])
    kid = heuristic_crossover(worse, better, 1.0, 0.5, alpha=np.array([0.5]))
    np.testing.assert_array_equal(kid, [0.0, 1.0, 0.5])


def test_heuristic_crossover_per_coordinate_bounds_and_clip_below():
    worse = np.array([0.9, 1.0])
    better = np.array([0.05, 1.5])
    # 0.9 + 1.2 (0.05 - 0.9) = -0.12 (below 0), 1 + 1.2 * 0.5 = 1.6 (inside [0, 2])
    np.testing.assert_allclose(
        heuristic_crossover(worse, better, 1.0, 0.5, lower=np.zeros(2), upper=np.array([1.0, 2.0]),
                            fallback="clip"), [0.0, 1.6])
    # the same bounds, random fallback with alpha = 0.25: 0.25 worse + 0.75 better
    np.testing.assert_allclose(
        heuristic_crossover(worse, better, 1.0, 0.5, lower=np.zeros(2), upper=np.array([1.0, 2.0]),
                            alpha=np.array([0.25])), [0.2625, 1.375])


def test_heuristic_crossover_errors():
    worse, better = np.array([0.1, 0.5]), np.array([0.95, 0.5])  # child 1.12: outside
    with pytest.raises(ValueError,
                       match=r"^the random fallback needs a random generator \(or alpha\)$"):
        heuristic_crossover(worse, better, 1.0, 0.5)
    with pytest.raises(ValueError, match="^unknown fallback 'reflect'; use 'random' or 'clip'$"):
        heuristic_crossover(worse, better, 1.0, 0.5, fallback="reflect")


# --- MADS basis ---------------------------------------------------------------------------
def test_mads_basis_keeps_its_diagonal_and_fills_the_lower_triangle():
    """LTMADS: L = diag(+-p) + strictly-lower integers floor((p + 1) U) in 0..p, permuted
    symmetrically (B = L[perm, perm]), so the diagonal of B is the diagonal of L."""
    rng = np.random.default_rng(11)
    p = 4.0  # step 1/16
    bases = [mads_basis(4, 1 / 16, rng) for _ in range(200)]
    lower_values, nonzero_off, negatives = set(), [], 0
    for B in bases:
        np.testing.assert_array_equal(np.abs(np.diag(B)), p)
        off = B[~np.eye(4, dtype=bool)]
        lower_values |= set(off.tolist())
        nonzero_off.append(int(np.count_nonzero(off)))
        negatives += int(np.sum(np.diag(B) < 0))
    assert lower_values == {0.0, 1.0, 2.0, 3.0, 4.0}  # 0 .. p, each equally likely
    assert max(nonzero_off) == 6  # all of the strictly-lower triangle of 4 x 4
    assert 300 < negatives < 500  # random signs: about half of the 800 diagonal entries


# --- active bounds and reach --------------------------------------------------------------
def test_active_bounds_of_a_shifted_box_at_exactly_the_tolerance():
    x = np.array([0.25, 0.5, 0.375, 0.75, 0.625])
    T = active_bound_directions(x, lower=0.25, upper=0.75, tol=0.125)
    # |0.25 - 0.25| = 0, |0.375 - 0.25| = 0.125 = tol, |0.75 - 0.75| = 0, |0.625 - 0.75| = tol;
    # 0.5 is 0.25 from both bounds
    np.testing.assert_array_equal(T, np.eye(5)[:, [0, 2, 3, 4]])


def test_max_feasible_length_of_one_direction_and_long_directions():
    x = np.array([0.2, 0.5, 1.0])
    assert max_feasible_length(x, np.array([2.0, 0.0, 0.0]), 0.0, 1.0) == pytest.approx(0.4)
    assert max_feasible_length(x, np.array([-2.0, 0.5, 0.0]), 0.0, 1.0) == pytest.approx(0.1)
    assert np.ndim(max_feasible_length(x, np.array([2.0, 0.0, 0.0]), 0.0, 1.0)) == 0
    np.testing.assert_allclose(
        max_feasible_length(x, np.array([[2.0, -4.0], [0.0, 0.0], [0.0, 0.0]]), 0.0, 1.0),
        [0.4, 0.05])
    # zero components (0/0 on the bound, 1/0 inside) divide silently and do not limit
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert max_feasible_length(x, np.array([0.0, 0.0, 0.0]), 0.0, 1.0) == np.inf


# --- adaptive feasible mutation -----------------------------------------------------------
def _moves(kids: np.ndarray, parents: np.ndarray) -> tuple[list[tuple[int, ...]], np.ndarray]:
    """The coordinates each child moved in, and the moves."""
    d = kids - parents
    return [tuple(np.flatnonzero(row).tolist()) for row in d], d


def test_mutation_moves_along_an_active_bound_when_the_basis_overshoots():
    """Box [0, 0.4]^4, step 1/4: every basis direction moves sqrt(1/4) = 0.5 along its
    diagonal coordinate (the box is narrower), so from a point within tol = 0.05 of a bound
    only the tangent directions fit, and they move exactly step = 0.25 (MATLAB's copy
    fallback is never needed there)."""
    rng = np.random.default_rng(3)
    hi = np.full(4, 0.4)
    for x0, sign in ((0.02, 1.0), (0.38, -1.0)):
        parents = np.full((30, 4), x0)
        kids = adaptive_feasible_mutation(parents, 0.25, rng, upper=hi, tol=0.05,
                                          fallback="copy")
        moved, d = _moves(kids, parents)
        assert all(len(m) == 1 for m in moved)                     # one coordinate each
        np.testing.assert_allclose(d.sum(axis=1), sign * 0.25)     # inward by the step


def test_mutation_takes_a_direction_that_fits_exactly():
    # box [0, 0.25]^4 from its lower corner: e_i reaches the upper bound at exactly step 1/4
    rng = np.random.default_rng(4)
    kids = adaptive_feasible_mutation(np.zeros((20, 4)), 0.25, rng, upper=0.25, fallback="copy")
    assert np.all(np.sort(kids, axis=1) == [0.0, 0.0, 0.0, 0.25])


def test_mutation_copy_fallback_still_moves_when_a_direction_fits():
    # from 0.9 in the unit box at step 1/4 (moves: diagonal +-0.5, below it 0, 0.25 or 0.5)
    # [B, -B] always holds a fitting direction: -B's column where B's sign is +, or the
    # column of B without lower entries
    rng = np.random.default_rng(6)
    parents = np.full((60, 4), 0.9)
    kids = adaptive_feasible_mutation(parents, 0.25, rng, fallback="copy")
    d = kids - parents
    assert np.all(np.abs(d).max(axis=1) == 0.5) and np.all(d.min(axis=1) == -0.5)


def test_mutation_shrink_halves_the_step_until_a_direction_fits():
    # box [0, 0.4]^4, from its centre-ish 0.2 (no active bound), step 1/4: the diagonal moves
    # 0.5 (t = 1/4) and 0.25 (t = 1/8) overshoot, 0.125 (t = 1/16) fits
    rng = np.random.default_rng(8)
    parents = np.full((30, 4), 0.2)
    kids = adaptive_feasible_mutation(parents, 0.25, rng, upper=0.4)
    d = np.abs(kids - parents)
    np.testing.assert_allclose(d.max(axis=1), 0.125)
    assert np.allclose(d * 16, np.round(d * 16))  # t = 1/16 times integer components


def test_mutation_of_integer_parents_and_per_coordinate_bounds():
    rng = np.random.default_rng(9)
    kids = adaptive_feasible_mutation(np.zeros((5, 2), dtype=int), 1 / 16, rng,
                                      lower=np.zeros(2), upper=np.array([1.0, 2.0]))
    assert kids.dtype == float and np.all(np.abs(kids).max(axis=1) > 0)
    assert np.all((kids >= 0) & (kids <= [1.0, 2.0]))


@pytest.mark.parametrize("lo, hi, x, step, end", [
    # x + (hi - x) rounds to 0.9000000000000001: the step that fits exactly overshoots by one
    # ulp and the child is clipped back onto the bound
    (0.3, 0.9, 0.30043058618692003, 0.59956941381308, 0.9),
    # x - (x - lo) rounds to 0.09999999999999998
    (0.1, 0.7, 0.699227825125808, 0.599227825125808, 0.1),
])
def test_mutation_clips_round_off_at_the_bound(lo, hi, x, step, end):
    # one dimension: the basis moves sqrt(step) ~ 0.77 (too far), the active bound's
    # direction reaches the other bound at exactly the step
    rng = np.random.default_rng(0)
    kid = adaptive_feasible_mutation(np.array([[x]]), step, rng, lower=lo, upper=hi,
                                     fallback="copy")
    assert kid[0, 0] == end


def test_mutation_rejects_an_unknown_fallback():
    with pytest.raises(ValueError, match="^unknown fallback 'grow'; use 'shrink' or 'copy'$"):
        adaptive_feasible_mutation(np.zeros((1, 2)), 0.5, np.random.default_rng(0),
                                   fallback="grow")


# --- stall test -----------------------------------------------------------------------------
@pytest.mark.parametrize("history, w, expected", [
    ([9.0, 7.0, 3.0, 3.0, 3.0], 2, True),    # best[-1] = best[-3] = 3: no change
    ([9.0, 7.0, 5.0, 3.0, 3.0], 2, False),   # 3 vs best[-3] = 5: 2 / (2 * 3) > 1e-6
    ([1.0, 1.0, 1.0, 0.5], 2, False),        # 0.5 vs 1
    ([5.0, 5.0, 1.0, 1.0, 1.0], 2, True),    # the latest best, not an early one
    ([4.0, 4.0], 1, True),                   # a one-generation window
])
def test_stall_test_compares_the_latest_best_with_the_one_w_generations_before(history, w,
                                                                               expected):
    assert stalled(np.array(history), w) == expected


def test_stall_test_defaults_edges_and_non_finite_bests():
    flat = np.full(51, 2e-4)
    assert stalled(flat) and not stalled(flat[:50])        # W = 50 by default
    assert stalled([2.0, 1.0], 1, function_tolerance=1.0)  # 1 / (1 * 1) = 1 <= 1
    assert not stalled([np.inf, np.inf, np.inf], 2)        # no finite best yet


def test_heuristic_crossover_flattens_column_shaped_scores_and_alphas():
    p1 = np.array([[0.2, 0.4], [0.1, 0.5]])
    p2 = np.array([[0.4, 0.5], [0.95, 0.5]])  # the second child, 1.12, is outside the box
    flat = heuristic_crossover(p1, p2, [1.0, 1.0], [0.5, 0.5], alpha=np.array([0.5, 0.25]))
    cols = heuristic_crossover(p1, p2, np.array([[1.0], [1.0]]), np.array([[0.5], [0.5]]),
                               alpha=np.array([[0.5], [0.25]]))
    np.testing.assert_allclose(flat, [[0.44, 0.52], [0.7375, 0.5]])
    np.testing.assert_array_equal(cols, flat)
