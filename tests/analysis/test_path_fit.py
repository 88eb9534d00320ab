"""Polynomial path functions (`analysis.path_fit`): OpenSim's term order, exact recovery of
polynomials, analytic derivatives, Latin-hypercube sampling."""
import math

import numpy as np
import pytest

from analysis import path_fit


@pytest.mark.parametrize("dim,order", [(1, 4), (2, 3), (3, 2), (3, 6), (4, 3)])
def test_term_count_and_uniqueness(dim, order):
    exps = path_fit.monomial_exponents(dim, order)
    assert len(exps) == math.comb(dim + order, order)
    assert len({tuple(e) for e in exps}) == len(exps)
    assert exps.sum(axis=1).max() == order and exps.min() == 0


@pytest.mark.oracle
@pytest.mark.parametrize("dim,order", [(1, 5), (2, 3), (3, 2), (3, 4)])
def test_term_order_is_opensims(dim, order):
    """Our term values equal opensim.MultivariatePolynomialFunction.getTermValues, term by term."""
    osim = pytest.importorskip("opensim")
    exps = path_fit.monomial_exponents(dim, order)
    x = np.array([1.3, -0.7, 0.45, 2.1])[:dim]
    fn = osim.MultivariatePolynomialFunction(osim.Vector([1.0] * len(exps)), dim, order)
    tv = fn.getTermValues(osim.Vector(list(x)))
    theirs = np.array([tv.get(i) for i in range(tv.size())])
    np.testing.assert_allclose(path_fit.design_matrix(x[None], exps)[0], theirs, rtol=1e-14)
    coef = np.random.default_rng(1).normal(size=len(exps))
    fn2 = osim.MultivariatePolynomialFunction(osim.Vector(list(coef)), dim, order)
    ours, arms = path_fit.evaluate(coef[None], exps, x[None])
    assert ours[0, 0] == pytest.approx(fn2.calcValue(osim.Vector(list(x))), rel=1e-13)
    for c in range(dim):   # OpenSim's analytic partial derivative
        d = fn2.calcDerivative(osim.StdVectorInt([c]), osim.Vector(list(x)))
        assert -arms[0, 0, c] == pytest.approx(d, rel=1e-12, abs=1e-14)


def test_fit_recovers_a_polynomial_exactly():
    """Data from a known degree-3 polynomial in 2 coordinates: the fit returns its coefficients."""
    rng = np.random.default_rng(0)
    exps = path_fit.monomial_exponents(2, 3)
    true = rng.normal(size=(4, len(exps)))
    q = rng.uniform(-1.5, 2.5, size=(60, 2))
    lengths, arms = path_fit.evaluate(true, exps, q)
    coef = path_fit.fit_polynomials(q, lengths, arms, 3)
    np.testing.assert_allclose(coef, true, atol=1e-10)
    coef_l = path_fit.fit_polynomials(q, lengths, None, 3)
    np.testing.assert_allclose(coef_l, true, atol=1e-9)


def test_gradient_matches_finite_differences():
    rng = np.random.default_rng(3)
    exps = path_fit.monomial_exponents(3, 4)
    coef = rng.normal(size=(2, len(exps)))
    q = rng.uniform(-1, 1, size=(5, 3))
    _, arms = path_fit.evaluate(coef, exps, q)
    h = 1e-6
    for c in range(3):
        dq = np.zeros(3)
        dq[c] = h
        lp, _ = path_fit.evaluate(coef, exps, q + dq)
        lm, _ = path_fit.evaluate(coef, exps, q - dq)
        np.testing.assert_allclose(-(lp - lm) / (2 * h), arms[:, :, c], atol=1e-8)


def test_select_orders_takes_the_lowest_order_that_fits():
    """A cubic in one coordinate: order 3 is chosen (orders 1-2 miss it, 3 is exact)."""
    q = np.linspace(-1, 2, 40)[:, None]
    qv = np.linspace(-0.9, 1.9, 17)[:, None]
    exps = path_fit.monomial_exponents(1, 3)
    true = np.array([[0.3, -0.02, 0.01, 0.004]])
    train = (q, *path_fit.evaluate(true, exps, q))
    val = (qv, *path_fit.evaluate(true, exps, qv))
    choice = path_fit.select_orders(train, val, max_order=6, length_tol=1e-6, moment_arm_tol=1e-6)
    assert choice.orders.tolist() == [3] and choice.ok.all()
    np.testing.assert_allclose(choice.coefficients[0], true[0], atol=1e-12)


def test_samples_are_latin_hypercube_around_the_frames():
    """One frame: each coordinate's offsets fill every one of the n strata of +-half width once."""
    rng = np.random.default_rng(5)
    frame = np.array([[0.5, 1.0, 5.0]])
    n = 200
    q = path_fit.sample_poses(frame, [0, 1], ["rotational", "translational"], n, rng)
    assert np.all(q[:, 2] == 5.0)                     # not a spanned coordinate: untouched
    for c, kind in ((0, "rotational"), (1, "translational")):
        u = (q[:, c] - frame[0, c]) / path_fit.SAMPLING_HALF_WIDTH[kind]    # in [-1, 1]
        strata = np.floor((u + 1) / 2 * n).astype(int)
        assert sorted(strata.tolist()) == list(range(n))
    # several frames: every frame is used (evenly)
    frames = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    q = path_fit.sample_poses(frames, [0], ["rotational"], 30, rng)
    nearest = np.abs(q[:, None, 0] - frames[None, :, 0]).argmin(axis=1)
    assert np.bincount(nearest).tolist() == [10, 10, 10]


def test_select_orders_refuses_too_few_poses():
    q = np.zeros((1, 3))
    with pytest.raises(ValueError, match="too few"):
        path_fit.select_orders((q, np.zeros((1, 2)), np.zeros((1, 2, 3))), (q, np.zeros((1, 2)), np.zeros((1, 2, 3))),
                               max_order=4, length_tol=1e-4, moment_arm_tol=1e-4)


def test_gated_fit_recovers_a_step_exactly():
    """A length with a ConditionalPathPoint-like step (a different polynomial while q0 <= 0.7):
    the gated fit returns both pieces exactly; a plain polynomial cannot (its error is the step's)."""
    rng = np.random.default_rng(5)
    exps = path_fit.monomial_exponents(2, 3)
    gates = ((0, -3.2, 0.7),)
    true = rng.normal(size=(3, 2 * len(exps)))
    q = rng.uniform(-0.5, 1.5, size=(80, 2))
    lengths, arms = path_fit.evaluate(true, exps, q, gates)
    active = path_fit.gate_activity(q, gates)[:, 0]
    assert 0 < active.sum() < len(q)
    coef = path_fit.fit_polynomials(q, lengths, arms, 3, gates)
    np.testing.assert_allclose(coef, true, atol=1e-9)
    plain = path_fit.fit_polynomials(q, lengths, arms, 3)
    lp, _ = path_fit.evaluate(plain, exps, q)
    assert np.abs(lp - lengths).max() > 1e-2


@pytest.mark.oracle
def test_expression_is_evaluated_by_opensim_as_ours():
    """The ExpressionBasedFunction text of a gated polynomial: OpenSim 4.6's value and analytic
    partial derivatives equal `path_fit.evaluate` on both sides of the gate."""
    osim = pytest.importorskip("opensim")
    if not hasattr(osim, "ExpressionBasedFunction"):
        pytest.skip("OpenSim < 4.5")
    rng = np.random.default_rng(7)
    exps = path_fit.monomial_exponents(3, 4)
    gates = ((0, -3.14160, 0.698142), (2, -0.2, 0.9))
    coef = rng.normal(size=len(exps) * 3)
    text = path_fit.expression(coef, exps, gates, ["q0", "q1", "q2"])
    fn = osim.ExpressionBasedFunction(text, osim.StdVectorString(["q0", "q1", "q2"]))
    for x in ([0.3, -0.4, 0.1], [0.8, 0.2, 0.5], [0.3, 0.1, 1.2], [0.9, -0.7, -0.5]):
        ours, arms = path_fit.evaluate(coef[None], exps, np.array([x]), gates)
        assert fn.calcValue(osim.Vector(x)) == pytest.approx(ours[0, 0], rel=1e-12, abs=1e-12)
        for c in range(3):
            d = fn.calcDerivative(osim.StdVectorInt([c]), osim.Vector(x))
            assert -arms[0, 0, c] == pytest.approx(d, rel=1e-10, abs=1e-10)


def test_higher_orders_only_for_few_coordinates():
    assert path_fit.max_order_for(1, 8) == 20
    assert path_fit.max_order_for(2, 8) == 20
    assert path_fit.max_order_for(3, 8) == 10
    assert path_fit.max_order_for(4, 8) == 8
    assert path_fit.n_terms(3, path_fit.max_order_for(3, 8)) <= 286
