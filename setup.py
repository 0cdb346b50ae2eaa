"""The one compiled part: plan/tour_search.c, path order's local search (plan/tour.py).

Optional: where no C compiler is found the build goes on without it and path order runs
the same search in Python, to the same tour (docs/plan.md, "Compiled search").
Everything else about the package is in pyproject.toml.
"""

from setuptools import Extension, setup

setup(ext_modules=[Extension(
    "galileo_cnc.plan._tour_search", ["galileo_cnc/plan/tour_search.c"], optional=True,
    # the same double arithmetic as Python's: no fused multiply-adds, no reordering
    extra_compile_args=["-O2", "-ffp-contract=off", "-fno-fast-math"])])
