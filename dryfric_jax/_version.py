"""The package version, recorded with every result (estimates, sweep records, figure runs).

It is raised with every change that alters the numbers a seed and settings give, or fixes a
result: a resumed sweep or figure reruns the points that an earlier version recorded instead of
reusing them (:mod:`dryfric_jax.sweep`, :mod:`dryfric_jax.figures.points`).
"""
__version__ = "0.3.1"
