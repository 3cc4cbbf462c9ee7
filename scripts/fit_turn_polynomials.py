"""Where the coefficients of ``dryfric_jax.boxmuller._COS`` and ``_SIN`` come from.

cos(pi r / 2) = C(r^2) and sin(pi r / 2) = r S(r^2) on |r| <= 1/2, fitted in y = r^2 on [0, 1/4]:
weighted least squares in 50-digit arithmetic at 200 Chebyshev nodes, relative error, iterated
toward the minimax fit by Lawson's reweighting (30 rounds).  Prints each fit's largest relative
error at the nodes and its coefficients (lowest degree first) as float64 literals.  The accuracy
of the rounded coefficients, as the engine evaluates them, is tested in ``tests/test_boxmuller.py``.

Needs mpmath (not a dependency of the package: ``pip install mpmath``); takes ~20 s::

    python scripts/fit_turn_polynomials.py
"""
import mpmath as mp

mp.mp.dps = 50
NODES = 200


def fit(f, terms: int, rounds: int = 30):
    """Coefficients of the polynomial in y of ``terms`` terms closest to ``f`` in relative error on
    [0, 1/4] (Lawson-reweighted least squares at the nodes), and its largest relative error."""
    ys = [mp.mpf(1) / 8 * (1 - mp.cos(mp.pi * (2 * i + 1) / (2 * NODES))) for i in range(NODES)]
    w = [mp.mpf(1)] * NODES
    for _ in range(rounds):
        A, b = mp.matrix(NODES, terms), mp.matrix(NODES, 1)
        for i, y in enumerate(ys):
            s = mp.sqrt(w[i]) / f(y)
            for j in range(terms):
                A[i, j] = y**j * s
            b[i] = s * f(y)
        c = mp.qr_solve(A, b)[0]
        err = [(sum(c[j] * y**j for j in range(terms)) - f(y)) / f(y) for y in ys]
        top = max(abs(e) for e in err)
        w = [wi * abs(e) / top for wi, e in zip(w, err)]
        total = sum(w)
        w = [wi / total * NODES for wi in w]
    return [c[j] for j in range(terms)], top


def sin_over_r(y):
    return mp.sin(mp.pi / 2 * mp.sqrt(y)) / mp.sqrt(y) if y > 0 else mp.pi / 2


def cos_(y):
    return mp.cos(mp.pi / 2 * mp.sqrt(y))


def main() -> None:
    for dtype, (n_cos, n_sin) in (("float64", (8, 7)), ("float32", (5, 4))):
        for name, f, n in (("_COS", cos_, n_cos), ("_SIN", sin_over_r, n_sin)):
            c, err = fit(f, n)
            print(f"{dtype} {name} ({n} terms, relative error {mp.nstr(err, 3)}): "
                  "(" + ", ".join(repr(float(x)) for x in c) + ")")


if __name__ == "__main__":
    main()
