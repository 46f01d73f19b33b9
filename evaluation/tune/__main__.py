"""``python -m evaluation.tune`` (:func:`evaluation.tune.cli.main`)."""

import sys

from evaluation.tune.cli import main

sys.exit(main())
