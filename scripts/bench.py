"""Throughput benchmark; same as ``dryfric bench``.  ``python scripts/bench.py [--json]``"""
import sys

from dryfric_jax.cli import main

if __name__ == "__main__":
    sys.exit(main(["bench", *sys.argv[1:]]))
