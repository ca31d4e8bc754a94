"""Known-answer generators and brute-force references for tests and benchmarks.

Nothing in the library imports this package (DESIGN.md, layers). Each submodule is re-exported
here so tests write ``from collide import testing`` and ``testing.<name>``.
"""
