"""Reproduce the paper's figures and tables: the same as ``dryfric figures``.

    python scripts/reproduce_figures.py --fig all --quick --out figs/
"""
import sys

if __name__ == "__main__":
    # named as the command before the package is imported, so that it behaves as ``dryfric``: a Ctrl-C
    # while JAX loads exits 130 with one line, as does an environment with too old a JAX, exit 2
    # (dryfric_jax.interrupts.launched_as_cli); it was a 20-33 line KeyboardInterrupt traceback
    sys.argv[0] = "dryfric"
    from dryfric_jax.cli import main

    sys.exit(main(["figures", *sys.argv[1:]]))
