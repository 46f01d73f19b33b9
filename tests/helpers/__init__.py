"""Support code several test files share (issue 61: one piece where the logic is the same).

tests/ is on pytest's path (the conftest's folder), so a test imports ``helpers.<module>``;
tests/conftest.py registers the package for pytest's assert rewriting, so an assert in a helper
reports its values as one in a test file does."""
