"""Tests of the paper's GA (solver ``paper-ga``) and its MATLAB ``ga`` operators.

Each operator is checked against a hand-computed case; the solver loop against the problem's
own counter (budget, one batch per generation), its seed, and its accuracy on the twin track.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import ema_bench_solvers.paper_ga  # noqa: F401  (registers "paper-ga")
from ema_bench import available_solvers, make_problem, run_solver
from ema_bench.faults import to_unit
from ema_bench_solvers.ga_operators import (
    MIN_STEP,
    active_bound_directions,
    adapt_step,
    adaptive_feasible_mutation,
    default_elite_count,
    heuristic_crossover,
    mads_basis,
    max_feasible_length,
    offspring_counts,
    parents_needed,
    rank_scaling,
    stalled,
    stochastic_uniform,
)
from ema_bench_solvers.paper_ga import _evaluate_unit, _individual_type, run_paper_ga


# --- population split ---------------------------------------------------------------------
@pytest.mark.parametrize("n, counts", [(100, (5, 76, 19)), (50, (3, 38, 9)), (20, (1, 15, 4)),
                                       (10, (1, 7, 2))])
def test_elite_crossover_mutant_counts(n, counts):
    assert offspring_counts(n) == counts
    assert default_elite_count(n) == math.ceil(0.05 * n)
    e, x, m = counts
    assert e + x + m == n
    assert parents_needed(x, m) == 2 * x + m


def test_counts_reject_bad_settings():
    with pytest.raises(ValueError):
        offspring_counts(10, elite_count=11)
    with pytest.raises(ValueError):
        offspring_counts(10, crossover_fraction=1.5)


# --- rank scaling -------------------------------------------------------------------------
def test_rank_scaling_hand_case():
    e = rank_scaling(np.array([3.0, 1.0, 2.0]), n_parents=6)
    raw = np.array([1 / math.sqrt(3), 1.0, 1 / math.sqrt(2)])
    np.testing.assert_allclose(e, 6 * raw / raw.sum())
    assert e.sum() == pytest.approx(6.0)
    assert e[1] > e[2] > e[0]  # the lowest score (best, minimising) expects the most


def test_rank_scaling_ignores_score_values_and_breaks_ties_in_order():
    a = rank_scaling(np.array([1e-9, 5.0, 1e12]), 3)
    b = rank_scaling(np.array([-7.0, 0.0, 0.1]), 3)
    np.testing.assert_allclose(a, b)  # only ranks matter (negative scores too)
    tie = rank_scaling(np.array([2.0, 2.0, 1.0]), 3)
    raw = np.array([1 / math.sqrt(2), 1 / math.sqrt(3), 1.0])
    np.testing.assert_allclose(tie, 3 * raw / raw.sum())


# --- stochastic uniform selection ---------------------------------------------------------
def test_stochastic_uniform_hand_case():
    # segments [0, 1.5) [1.5, 2) [2, 3) [3, 4); step = 4/4 = 1; pointers 0.4, 1.4, 2.4, 3.4
    e = np.array([1.5, 0.5, 1.0, 1.0])
    np.testing.assert_array_equal(stochastic_uniform(e, 4, start=0.4), [0, 0, 2, 3])
    # pointers 0.6, 1.6, 2.6, 3.6: the second falls in the small segment
    np.testing.assert_array_equal(stochastic_uniform(e, 4, start=0.6), [0, 1, 2, 3])
    # pointers on segment boundaries belong to the next segment (position < cumsum)
    np.testing.assert_array_equal(stochastic_uniform(e, 4, start=0.0), [0, 0, 2, 3])
    # 3 parents from expectations summing to 4: step 4/3, pointers 0.5, 1.833, 3.167
    np.testing.assert_array_equal(stochastic_uniform(e, 3, start=0.5), [0, 1, 3])
    with pytest.raises(ValueError):
        stochastic_uniform(e, 4, start=1.0)  # start must lie in [0, step)


def test_stochastic_uniform_picks_each_floor_or_ceil_of_its_expectation():
    rng = np.random.default_rng(3)
    for _ in range(20):
        scores = rng.random(30)
        e = rank_scaling(scores, 44)
        idx = stochastic_uniform(e, 44, rng=rng)
        counts = np.bincount(idx, minlength=30)
        assert counts.sum() == 44
        assert np.all(counts >= np.floor(e - 1e-9)) and np.all(counts <= np.ceil(e + 1e-9))


# --- heuristic crossover ------------------------------------------------------------------
def test_heuristic_crossover_hand_case():
    worse = np.array([0.2, 0.4, 0.5, 0.5])
    better = np.array([0.4, 0.5, 0.5, 0.6])
    expected = [0.44, 0.52, 0.5, 0.62]  # worse + 1.2 (better - worse)
    np.testing.assert_allclose(heuristic_crossover(worse, better, 1.0, 0.5), expected)
    np.testing.assert_allclose(heuristic_crossover(better, worse, 0.5, 1.0), expected)
    # tie: MATLAB takes parent 2 as the better one
    np.testing.assert_allclose(heuristic_crossover(worse, better, 1.0, 1.0), expected)
    # batched pairs
    kids = heuristic_crossover(np.array([worse, better]), np.array([better, worse]),
                               [1.0, 0.5], [0.5, 1.0])
    np.testing.assert_allclose(kids, [expected, expected])


def test_heuristic_crossover_feasible_fallback():
    worse = np.array([0.1, 0.5, 0.5, 0.5])
    better = np.array([0.95, 0.5, 0.5, 0.5])  # 0.1 + 1.2 * 0.85 = 1.12: out of the box
    # MATLAB: a random convex combination alpha p1 + (1 - alpha) p2 of the parents
    kid = heuristic_crossover(worse, better, 1.0, 0.5, alpha=np.array([0.25]))
    np.testing.assert_allclose(kid, 0.25 * worse + 0.75 * better)
    kid = heuristic_crossover(worse, better, 1.0, 0.5, rng=np.random.default_rng(0))
    assert np.all((kid >= 0) & (kid <= 1)) and worse[0] <= kid[0] <= better[0]
    # documented alternative: clip to the box
    kid = heuristic_crossover(worse, better, 1.0, 0.5, fallback="clip")
    np.testing.assert_allclose(kid, [1.0, 0.5, 0.5, 0.5])
    # a feasible child is never touched by the fallback
    kids = heuristic_crossover(np.array([worse, [0.2, 0.4, 0.5, 0.5]]),
                               np.array([better, [0.4, 0.5, 0.5, 0.6]]), [1.0, 1.0],
                               [0.5, 0.5], alpha=np.array([0.25, 0.25]))
    np.testing.assert_allclose(kids[1], [0.44, 0.52, 0.5, 0.62])


# --- adaptive feasible mutation -----------------------------------------------------------
def test_adaptive_step_grows_and_shrinks_four_times():
    assert adapt_step(1 / 16, improved=True) == pytest.approx(1 / 4)
    assert adapt_step(1 / 4, improved=False) == pytest.approx(1 / 16)
    assert adapt_step(0.5, improved=True) == 1.0          # capped at the box size
    assert adapt_step(MIN_STEP, improved=False) == MIN_STEP  # floored at sqrt(eps)
    assert MIN_STEP == pytest.approx(math.sqrt(np.finfo(float).eps))


def test_mads_basis_is_a_permuted_lower_triangular_basis():
    rng = np.random.default_rng(1)
    for step in (1.0, 1 / 4, 1 / 16, 1e-4):
        B = mads_basis(4, step, rng)
        p = 1 / math.sqrt(step)
        assert np.linalg.matrix_rank(B) == 4
        big = np.abs(np.abs(B) - p) < 1e-9 * p
        assert np.all(big.sum(axis=0) >= 1)  # one +-p (diagonal) entry per column
        off = B[~big]
        assert np.all(off == np.round(off)) and np.all((off >= 0) & (off < p + 1))


def test_active_bound_directions_and_reach():
    T = active_bound_directions(np.array([0.0, 0.5, 1.0, 0.9995]))
    np.testing.assert_array_equal(T, np.eye(4)[:, [0, 2, 3]])
    x = np.array([0.2, 0.5, 1.0, 0.0])
    D = np.array([[1.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
    np.testing.assert_allclose(max_feasible_length(x, D, 0.0, 1.0), [0.5, 0.2, 0.0])


@pytest.mark.parametrize("step", [1.0, 0.25, 1e-2, 1e-6, MIN_STEP])
def test_mutation_keeps_children_inside_the_box(step):
    rng = np.random.default_rng(7)
    parents = np.concatenate([rng.random((40, 4)), np.eye(4), 1 - np.eye(4), np.zeros((1, 4)),
                              np.ones((1, 4)), [[0.0, 1.0, 0.0, 1.0], [1e-4, 0.5, 1.0, 0.3]]])
    kids = adaptive_feasible_mutation(parents, step, rng)
    assert kids.shape == parents.shape
    assert np.all((kids >= 0.0) & (kids <= 1.0))
    moved = np.abs(kids - parents).max(axis=1)
    assert np.all(moved > 0)  # the shrink fallback always moves
    # a step moves at most step * (p + 1) per coordinate, p = 1/sqrt(step)
    assert np.all(moved <= step * (1 / math.sqrt(step) + 1) + 1e-12)


def test_mutation_small_step_uses_the_full_step_and_matlab_copy_fallback():
    rng = np.random.default_rng(2)
    x = np.full((1, 4), 0.5)
    for _ in range(10):
        # p = 4: the diagonal entry moves 4/16 = 0.25, the others k/16, k = 0..4
        d = np.abs(adaptive_feasible_mutation(x, 1 / 16, rng) - x)[0]
        assert d.max() == pytest.approx(0.25) and np.allclose(d * 16, np.round(d * 16))
    # at step 1 no direction fits from the centre: MATLAB copies the parent
    np.testing.assert_array_equal(adaptive_feasible_mutation(x, 1.0, rng, fallback="copy"), x)


# --- stall test -----------------------------------------------------------------------------
def test_stall_test_hand_cases():
    flat = np.full(51, 2e-4)
    assert stalled(flat, 50)
    assert not stalled(flat[:50], 50)  # needs 50 generations after generation 0
    falling = np.linspace(1e-4, 0.9e-4, 51)
    # change 1e-5 over 50 generations: relative 1e-5 / (50 * 0.9e-4) = 2.2e-3 > 1e-6
    assert not stalled(falling, 50)
    # MATLAB's max(1, |f|) makes it absolute: 1e-5 / 50 = 2e-7 <= 1e-6
    assert stalled(falling, 50, floor=1.0)
    assert stalled(np.zeros(6), 5)


# --- the solver on real problems ----------------------------------------------------------
def test_registered():
    info = available_solvers()["paper-ga"]
    assert info.library == "deap"


def _spy_on_evaluate(monkeypatch, p):
    sizes = []
    real = p._log.evaluate_outputs   # where every evaluation is counted: the solver has a view

    def spy(X):
        assert len(X) <= p.remaining
        sizes.append(len(X))
        return real(X)

    monkeypatch.setattr(p._log, "evaluate_outputs", spy)
    return sizes


def test_never_exceeds_the_budget_and_one_batch_per_generation(monkeypatch):
    p = make_problem("small", track="twin", seed=0, budget=10_000)
    sizes = _spy_on_evaluate(monkeypatch, p)
    p.limit(250)
    run = run_paper_ga(p, seed=0, population=100)
    assert p.evaluations == 250
    assert sizes == [100, 95, 55]  # 5 elites kept; the last generation truncated to what is left
    assert run.stop_reason == "budget" and run.generations == 2


def test_run_solver_budget_and_record(monkeypatch):
    p = make_problem("small", track="twin", seed=0, budget=10_000)
    sizes = _spy_on_evaluate(monkeypatch, p)
    res = run_solver("paper-ga", p, budget=250, seed=0)
    assert res.evaluations == p.evaluations == 250
    assert sizes == [80, 76, 76, 18]  # default N = 80: 4 elites
    assert res.stop_reason == "budget"
    assert res.extra["population"] == 80 and res.extra["generations"] == 3
    assert "deap" in res.library


def test_budget_smaller_than_the_population():
    p = make_problem("nominal", track="twin", seed=0, budget=30)
    res = run_solver("paper-ga", p, seed=0)
    assert res.evaluations == 30 and res.stop_reason == "budget"


def test_nominal_vector_in_initial_population():
    p = make_problem("full", track="twin", seed=0, budget=100)
    run_solver("paper-ga", p, seed=5)
    X = p.history()["x"]
    assert any(np.allclose(x, p.nominal) for x in X)
    # the rest is uniform over the bounds (initial range = bounds)
    U = to_unit(X)
    assert np.all((U >= 0) & (U <= 1)) and U.min(axis=0).max() < 0.2 and U.max(axis=0).min() > 0.8


def test_augmented_problem_searches_every_dimension():
    p = make_problem("small", track="twin", seed=0, budget=150, augment=("viscous_friction",))
    res = run_solver("paper-ga", p, seed=0)
    assert res.evaluations == 150 and p.dim == 5 and res.x.shape == (5,)
    X = p.history()["x"]
    assert np.allclose(X[0], p.nominal) and np.ptp(X[:, 4]) > 0


def test_max_generations_stop():
    p = make_problem("small", track="twin", seed=0, budget=2000)
    run = run_paper_ga(p, seed=0, population=20, max_generations=3)
    assert run.stop_reason == "max_generations" and run.generations == 3
    assert p.evaluations == 20 + 3 * 19
    assert [r["gen"] for r in run.logbook] == [0, 1, 2, 3]


def test_stall_stop():
    p = make_problem("nominal", track="twin", seed=0, budget=2000)
    run = run_paper_ga(p, seed=0, population=10, stall_generations=3, function_tolerance=1.0)
    assert run.stop_reason == "stall" and run.generations == 3
    assert p.evaluations == 10 + 3 * 9


def test_same_seed_same_result():
    def go(seed):
        p = make_problem("random", track="twin", seed=0, budget=600)
        r = run_solver("paper-ga", p, seed=seed)
        return r, p.history()

    (r1, h1), (r2, h2), (_, h3) = go(4), go(4), go(5)
    np.testing.assert_array_equal(h1["x"], h2["x"])
    np.testing.assert_array_equal(r1.x, r2.x)
    assert r1.fitness == r2.fitness and r1.evaluations == r2.evaluations
    assert not np.array_equal(h1["x"][1:], h3["x"][1:])


# slow, the GA's accuracy at budget 5000 (four runs, about 10 CPU-s; also left out of the
# mutation runs): the fast loop checks its operators, seeding, budget and loop by hand
@pytest.mark.slow
def test_identifies_the_faults_on_the_twin_track_full():
    p = make_problem("full", track="twin", seed=0, budget=5000)
    res = run_solver("paper-ga", p, seed=0)
    assert res.evaluations <= 5000
    score = p.score(res.x)
    assert score.success, score.range_error


@pytest.mark.slow
def test_approaches_the_optimum_of_the_small_case():
    # the small case's Na/Fst valley is shallow: at budget 5000 the GA ends inside it, near
    # the optimum, and within 1 % of every range on about half the seeds (measured, seeds
    # 0-5: fitness 0-3 % above the truth's, 3 of 6 successes, Na off by 0.3-3.3 % of its
    # range).  One seed would test luck; this pins what every run delivers.
    wins = 0
    for seed in range(3):
        p = make_problem("small", track="twin", seed=seed, budget=5000)
        res = run_solver("paper-ga", p, seed=seed)
        assert res.evaluations <= 5000
        assert res.fitness <= 1.05 * p.fitness_at_truth()
        score = p.score(res.x)
        assert max(score.range_error.values()) < 0.05, score.range_error
        wins += score.success
    assert wins >= 1


def test_generation_loop_keeps_the_elites_and_adapts_the_step_as_matlab():
    """The loop wires the operators as MATLAB's ga does, traced by hand from the logbook:
    elitism (the best score of the population never worsens: the elites are the best
    individuals, carried over unevaluated) and mutationadaptfeasible's step rule (1 for
    generations 1-2, then x4 after a generation that improved the best, /4 otherwise,
    within [sqrt(eps), 1])."""
    p = make_problem("small", track="twin", seed=0, budget=40 * 20)
    run = run_paper_ga(p, seed=3, population=20, stall_generations=1000)
    log = run.logbook
    best = np.array(log.select("best"))
    steps = np.array(log.select("step"))
    nevals = np.array(log.select("nevals"))
    assert run.generations >= 30
    assert np.all(np.diff(best) <= 0.0)                   # elitism
    # each generation evaluates N - elites = 20 - ceil(0.05 * 20) = 19 new individuals
    assert nevals[0] == 20 and np.all(nevals[1:-1] == 19)
    assert steps[1] == steps[2] == 1.0
    improved_seen = shrunk_seen = False
    for g in range(3, len(steps)):
        improved = best[g - 1] < best[g - 2]
        want = min(1.0, 4.0 * steps[g - 1]) if improved else max(MIN_STEP, steps[g - 1] / 4.0)
        assert steps[g] == want, (g, improved, steps[g - 1], steps[g])
        improved_seen |= improved
        shrunk_seen |= not improved
    assert improved_seen and shrunk_seen                 # both branches were exercised


# --- the loop on a stand-in problem -----------------------------------------------------------
# What run_paper_ga uses of a Problem, on the unit box with a fitness that costs nothing, so
# the loop can be followed generation by generation: every scored batch is kept.
class BoxProblem:
    def __init__(self, fitness, budget: int, dim: int = 4, start=None) -> None:
        self.fitness, self.budget, self.dim = fitness, budget, dim
        self.start = np.full(dim, 0.5) if start is None else np.asarray(start, float)
        self.evaluations = 0
        self.batches: list[np.ndarray] = []
        self.scores: list[np.ndarray] = []

    @property
    def remaining(self) -> int:
        return self.budget - self.evaluations

    def to_unit(self, X):
        return np.asarray(X, dtype=float)  # the box is [0, 1]^dim

    def from_unit(self, U):
        return np.asarray(U, dtype=float)

    def evaluate(self, X):
        X = np.array(X, dtype=float)
        assert 0 < len(X) <= self.remaining
        f = np.asarray(self.fitness(X), dtype=float)
        self.evaluations += len(X)
        self.batches.append(X)
        self.scores.append(f)
        return f


TARGET = np.array([0.8, 0.3, 0.6, 0.2])


def sphere(X):
    return np.sum((X - TARGET) ** 2, axis=1)


def constant(X):
    return np.ones(len(X))


def test_loop_record_and_logbook_by_hand():
    # N = 80: ceil(4) = 4 elites, round(0.8 * 76) = 61 crossover children, 15 mutants
    p = BoxProblem(sphere, budget=80 + 3 * 76)
    run = run_paper_ga(p)
    assert (run.population, run.elite_count, run.n_crossover, run.n_mutants) == (80, 4, 61, 15)
    assert run.stop_reason == "budget" and run.generations == 3
    assert [len(b) for b in p.batches] == [80, 76, 76, 76]
    # the default seed is 0
    q = BoxProblem(sphere, budget=80 + 3 * 76)
    run_paper_ga(q, seed=0)
    for a, b in zip(p.batches, q.batches):
        np.testing.assert_array_equal(a, b)
    # the logbook, generation by generation, from the scored batches: the population of
    # generation g is the 4 best of generation g - 1 (unevaluated) and the new children
    log = run.logbook
    assert str(log).splitlines()[0].split() == ["gen", "nevals", "best", "mean", "step",
                                                "best_xover", "best_mutant"]
    pop = p.scores[0]
    assert log[0] == {"gen": 0, "nevals": 80, "best": pop.min(), "mean": pytest.approx(pop.mean()),
                      "step": 1.0, "best_xover": np.inf, "best_mutant": np.inf}
    for g in (1, 2, 3):
        kids = p.scores[g]
        pop = np.concatenate([np.sort(pop)[:4], kids])
        assert log[g]["gen"] == g and log[g]["nevals"] == 76
        assert log[g]["best"] == pop.min()
        assert log[g]["mean"] == pytest.approx(pop.mean(), rel=1e-12)
        assert log[g]["best_xover"] == kids[:61].min()
        assert log[g]["best_mutant"] == kids[61:].min()
    assert run.final_step == log[3]["step"]


def test_loop_settings_reach_the_operators():
    p = BoxProblem(sphere, budget=10_000)
    run = run_paper_ga(p, population=20, elite_count=0, crossover_fraction=0.5,
                       max_generations=2)
    assert (run.elite_count, run.n_crossover, run.n_mutants) == (0, 10, 10)
    assert [len(b) for b in p.batches] == [20, 20, 20]  # no elites: all 20 are new
    # no crossover at all: the logbook's best crossover child is +inf
    p = BoxProblem(sphere, budget=10_000)
    run = run_paper_ga(p, population=10, crossover_fraction=0.0, max_generations=2)
    assert run.n_crossover == 0 and [r["best_xover"] for r in run.logbook] == [np.inf] * 3
    # the smallest population: one elite and one crossover child per generation
    p = BoxProblem(sphere, budget=10_000)
    run = run_paper_ga(p, population=2, max_generations=3)
    assert (run.elite_count, run.n_crossover, run.n_mutants) == (1, 1, 0)
    assert p.evaluations == 2 + 3 and run.stop_reason == "max_generations"
    # max_generations = 0: the initial population only
    p = BoxProblem(sphere, budget=10_000)
    run = run_paper_ga(p, max_generations=0)
    assert run.generations == 0 and run.stop_reason == "max_generations" and p.evaluations == 80


def test_loop_refuses_bad_settings_by_name():
    p = BoxProblem(sphere, budget=100)
    with pytest.raises(ValueError, match="^population must be at least 2, got 1$"):
        run_paper_ga(p, population=1)
    with pytest.raises(ValueError, match="^max_generations must be >= 0, got -1$"):
        run_paper_ga(p, max_generations=-1)
    assert p.evaluations == 0


@pytest.mark.parametrize("budget, generations, evaluations", [
    (0, 0, 0),                # nothing left: no population, no generation
    (1, 0, 1),                # one individual: scored, but no full population to breed
    (80, 0, 80),              # exactly the initial population
    (81, 1, 81),              # one child more
    (80 + 76 + 1, 2, 157),    # a generation, then one child
])
def test_loop_spends_the_budget_to_the_last_evaluation(budget, generations, evaluations):
    p = BoxProblem(sphere, budget=budget)
    run = run_paper_ga(p)
    assert (run.generations, p.evaluations, run.stop_reason) == (generations, evaluations,
                                                                 "budget")
    if budget == 0:
        assert run.logbook[0]["best"] == np.inf and run.logbook[0]["mean"] == np.inf


def test_loop_budget_argument_caps_what_the_problem_allows():
    p = BoxProblem(sphere, budget=10_000)
    run = run_paper_ga(p, budget=100)
    assert p.evaluations == 100 and run.stop_reason == "budget"


def test_loop_stalls_after_fifty_generations_without_change():
    # constant fitness: the best never changes, MATLAB's stall test stops at generation 50
    p = BoxProblem(constant, budget=100_000)
    run = run_paper_ga(p)
    assert run.stop_reason == "stall" and run.generations == 50
    # ... unless the budget ends with that very generation: the budget is the reason then
    p = BoxProblem(constant, budget=80 + 50 * 76)
    run = run_paper_ga(p)
    assert run.stop_reason == "budget" and run.generations == 50


def test_loop_stall_tolerance_and_floor():
    # f = 1e-5 (1 + |u - t|^2): improving by far more than 1e-6 relative, so no stall (the
    # relative test); MATLAB's floor of 1 makes it an absolute test, which 1e-5-sized
    # changes pass: a stall at generation 50
    def small(X):
        return 1e-5 * (1.0 + sphere(X))

    run = run_paper_ga(BoxProblem(small, budget=100_000), max_generations=50)
    assert run.stop_reason == "max_generations"
    run = run_paper_ga(BoxProblem(small, budget=100_000), max_generations=50, stall_floor=1.0)
    assert run.stop_reason == "stall" and run.generations == 50

    # f = 1 + 1e-9 |u - t|^2: it improves, but by less than 1e-6 relative over 50 generations
    def flat(X):
        return 1.0 + 1e-9 * sphere(X)

    run = run_paper_ga(BoxProblem(flat, budget=80 + 60 * 76))
    assert run.stop_reason == "stall" and run.generations == 50


def test_loop_step_rule_without_improvement():
    # no generation improves: the step is 1 for generations 0-2, then shrinks 4 times per
    # generation down to the given floor
    p = BoxProblem(constant, budget=100_000)
    run = run_paper_ga(p, max_generations=9, min_step=1e-3)
    assert run.logbook.select("step") == [1.0, 1.0, 1.0, 0.25, 0.0625, 0.015625, 0.00390625,
                                          1e-3, 1e-3, 1e-3]


def _crossover_pairs(U, s, kids, ratio):
    """For each child: the pairs (better, worse) of the population with
    ``kid = worse + ratio (better - worse)``, and whether it is a convex combination of a
    pair instead (the feasible fallback)."""
    b = U[:, None, :]
    w = U[None, :, :]
    line = w + ratio * (b - w)                                   # [better, worse]
    heuristic = []
    convex = []
    for kid in kids:
        hit = np.argwhere(np.all(np.abs(line - kid) < 1e-12, axis=2))
        heuristic.append([(i, j) for i, j in hit if s[i] <= s[j]])
        d = kid - w                                              # kid = worse + a (b - w)
        span = b - w
        with np.errstate(invalid="ignore", divide="ignore"):
            a = np.sum(d * span, axis=2) / np.sum(span * span, axis=2)
        resid = np.abs(d - a[:, :, None] * span).max(axis=2)
        convex.append(bool(np.any((resid < 1e-12) & (a >= 0) & (a <= 1))))
    return heuristic, convex


def test_crossover_children_extrapolate_from_the_worse_past_the_better_parent():
    p = BoxProblem(sphere, budget=80 + 76)
    run_paper_ga(p, seed=2)
    U, s = p.batches[0], p.scores[0]
    heuristic, convex = _crossover_pairs(U, s, p.batches[1][:61], 1.2)
    # every child is worse + 1.2 (better - worse) of a pair, the better being the one with
    # the lower score, or (outside the box) a point between the two
    assert all(h or c for h, c in zip(heuristic, convex))
    assert sum(bool(h) for h in heuristic) >= 30
    # the pairs come from the whole population, not one individual, and are not all copies
    parents = {k for h in heuristic for pair in h for k in pair}
    assert len(parents) >= 20 and int(np.argmin(s)) in parents
    copies = sum(bool(np.any(np.all(U == kid, axis=1))) for kid in p.batches[1][:61])
    assert copies <= 10


def test_crossover_ratio_and_mutation_fallback_reach_the_operators():
    # ratio 1: every child is its better parent
    p = BoxProblem(sphere, budget=80 + 76)
    run_paper_ga(p, crossover_ratio=1.0)
    U = p.batches[0]
    for kid in p.batches[1][:61]:
        assert np.any(np.all(np.abs(U - kid) < 1e-12, axis=1))
    # MATLAB's copy fallback: at step 1 no direction fits from inside the box, so the
    # generation-1 mutants are copies of their parents; the default shrink moves them
    for fallback, copies in (("copy", 15), ("shrink", 0)):
        p = BoxProblem(sphere, budget=80 + 76)
        run_paper_ga(p, mutation_fallback=fallback)
        U = p.batches[0]
        assert sum(bool(np.any(np.all(U == kid, axis=1))) for kid in p.batches[1][61:]) == copies


def test_the_mutation_space_and_the_nominal_individual_by_their_settings():
    """An unknown mutation space is refused by name before any evaluation; the fallback
    reaches the mutation in the problem's units too (on the unit box the two spaces agree:
    MATLAB's copy fallback copies all 15 generation-1 mutants); ``include_nominal=False``
    leaves the start vector out of generation 0."""
    p = BoxProblem(sphere, budget=100)
    with pytest.raises(ValueError, match=r"^mutation_space must be one of \['unit', "
                                         r"'units'\], got 'metres'$"):
        run_paper_ga(p, mutation_space="metres")
    assert p.evaluations == 0
    for fallback, copies in (("copy", 15), ("shrink", 0)):
        p = BoxProblem(sphere, budget=80 + 76)
        p.lower, p.upper = np.zeros(4), np.ones(4)
        run_paper_ga(p, mutation_fallback=fallback, mutation_space="units")
        U = p.batches[0]
        assert sum(bool(np.any(np.all(U == kid, axis=1))) for kid in p.batches[1][61:]) == copies
    start = np.full(4, 0.25)
    for include, first_is_start in ((True, True), (False, False)):
        p = BoxProblem(sphere, budget=80, start=start)
        run_paper_ga(p, include_nominal=include, max_generations=0)
        assert bool(np.all(p.batches[0][0] == start)) is first_is_start
        assert np.sum(np.all(p.batches[0] == start, axis=1)) == int(first_is_start)


def test_elites_are_the_best_with_ties_in_population_order(monkeypatch):
    """MATLAB sorts stably: among individuals with the same score the earlier ones are the
    elites, in that order, at the head of the next population.  A scaling that gives the
    first four places of the population the expectations 8 : 4 : 2 : 1 (and the rest none)
    shows who is where: generation 2's parents are generation 1's elites, each as often as
    its place says."""
    import ema_bench_solvers.paper_ga as paper_ga

    weights = np.array([8.0, 4.0, 2.0, 1.0])

    def first_four(scores, n_parents):
        e = np.zeros(len(scores))
        e[:4] = weights
        return n_parents * e / e.sum()

    parents: list[np.ndarray] = []
    real_mate, real_mutate = paper_ga.heuristic_crossover, paper_ga.adaptive_feasible_mutation

    def mate(p1, p2, *args, **kwargs):
        parents.append(np.concatenate([p1, p2]))
        return real_mate(p1, p2, *args, **kwargs)

    def mutate(X, *args, **kwargs):
        parents.append(X)
        return real_mutate(X, *args, **kwargs)

    monkeypatch.setattr(paper_ga, "rank_scaling", first_four)
    monkeypatch.setattr(paper_ga, "heuristic_crossover", mate)
    monkeypatch.setattr(paper_ga, "adaptive_feasible_mutation", mutate)

    def levels(X):  # four levels of score: about 20 individuals tie at each
        return np.floor(4 * X[:, 0])

    for seed in range(5):
        parents.clear()
        p = BoxProblem(levels, budget=80 + 2 * 76)
        run_paper_ga(p, seed=seed)
        U, s = p.batches[0], p.scores[0]
        best = np.flatnonzero(s == s.min())
        assert len(best) > 10
        gen2 = np.concatenate(parents[2:])  # calls: mate and mutate of generation 1, then 2
        assert len(gen2) == 137             # 2 * 61 + 15 parents
        # 137 parents in the ratio 8 : 4 : 2 : 1 are 73.1, 36.5, 18.3 and 9.1 expected
        counts = [int(np.sum(np.all(gen2 == U[i], axis=1))) for i in best[:4]]
        for c, lo in zip(counts, (73, 36, 18, 9)):
            assert lo <= c <= lo + 1, (seed, counts)


def test_evaluate_unit_clips_into_the_box_and_skips_empty_batches():
    p = BoxProblem(lambda X: X.sum(axis=1), budget=10)
    f = _evaluate_unit(p, np.array([[-0.5, 1.5, 0.25, 1.0]]))
    assert f.tolist() == [2.25] and p.batches[0].tolist() == [[0.0, 1.0, 0.25, 1.0]]
    empty = _evaluate_unit(p, np.empty((0, 4)))
    assert empty.shape == (0,) and len(p.batches) == 1 and p.evaluations == 1


def test_deap_types_are_created_once_and_minimise(monkeypatch):
    from deap import base, creator

    monkeypatch.delattr(creator, "PaperGAFitnessMin", raising=False)
    monkeypatch.delattr(creator, "PaperGAIndividual", raising=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # DEAP warns when a type is created again
        Individual = _individual_type()
        assert _individual_type() is Individual
    fitness = creator.PaperGAFitnessMin
    assert issubclass(fitness, base.Fitness) and fitness.weights == (-1.0,)
    assert Individual.__name__ == "PaperGAIndividual" and issubclass(Individual, list)
    good, bad = Individual([0.1, 0.2]), Individual([0.3, 0.4])
    assert good == [0.1, 0.2]
    good.fitness.values, bad.fitness.values = (1.0,), (2.0,)
    assert good.fitness > bad.fitness  # the lower score is the fitter one


def test_paper_ga_units_mutates_in_the_problems_units():
    """``paper-ga-units`` (MATLAB's mutation, in physical units) and ``paper-ga`` (the unit
    box) are both registered and say which is which.  In units, a step of size 1 is 1 /s of
    a gain whose range is 1e5 /s: the gain hardly moves (under 1e-3 of its range) while Na,
    whose range is 0.2, moves a lot; in the box both move alike."""
    from ema_bench_solvers.ga_operators import adaptive_feasible_mutation
    from ema_bench_solvers.paper_ga import _mutate_in_units

    infos = available_solvers()
    assert "problem's units" in infos["paper-ga-units"].description
    assert "[0, 1] box" in infos["paper-ga"].description
    assert infos["paper-ga-units"].config == {"mutation_space": "units"}
    p = make_problem("small", track="twin", seed=0, budget=1)
    U = np.random.default_rng(0).uniform(0.2, 0.8, (50, 4))
    kids_units = _mutate_in_units(p, U, 1.0, rng=np.random.default_rng(1))
    kids_box = adaptive_feasible_mutation(U, 1.0, np.random.default_rng(1))
    d_units, d_box = np.abs(kids_units - U), np.abs(kids_box - U)
    moved = (d_units > 1e-9).mean(axis=0)
    assert moved[0] < 0.2 and moved[2] < 0.2 and moved[3] > 0.5
    assert d_units[:, 3].max() < 1e-4
    assert np.all(d_box.mean(axis=0) > 0.1)
    assert np.all((kids_units >= 0.0) & (kids_units <= 1.0))
    # end to end: a run is counted by the problem and reproducible
    runs = []
    for _ in range(2):
        q = make_problem("small", track="twin", seed=0, budget=200)
        res = run_solver("paper-ga-units", q, seed=3)
        assert q.evaluations == 200 and res.solver == "paper-ga-units"
        runs.append(q.history()["x"])
    assert np.array_equal(*runs)
