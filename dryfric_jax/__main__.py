"""``python -m dryfric_jax ...`` runs the ``dryfric`` command line (:mod:`dryfric_jax.cli`)."""
import sys

from .cli import main

sys.exit(main())
