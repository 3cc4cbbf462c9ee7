"""Reproduce the paper's figures and tables: the same as ``dryfric figures``.

    python scripts/reproduce_figures.py --fig all --quick --out figs/
"""
import sys

from dryfric_jax.cli import main

if __name__ == "__main__":
    sys.exit(main(["figures", *sys.argv[1:]]))
