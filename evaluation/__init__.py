"""The evaluator's parts: controller configurations, statistics, ablations (``evaluate.py`` is the entry point)."""
