"""The compiled parts: plan/order/tour_search.c, path order's local search
(plan/order/tour.py), and plan/ink/edge_index.c, the ink's grid index of edges
(plan/ink/edges.py).

Optional: where no C compiler is found the build goes on without them and the planner
runs the same searches in Python and numpy, to the same answers (docs/plan.md,
"Compiled search"). Everything else about the package is in pyproject.toml.
"""

from setuptools import Extension, setup

#: the same double arithmetic as Python's and numpy's: no fused multiply-adds, no reordering
SAME_ARITHMETIC = ["-O2", "-ffp-contract=off", "-fno-fast-math"]

setup(ext_modules=[
    Extension("galileo_cnc.plan.order._tour_search", ["galileo_cnc/plan/order/tour_search.c"],
              optional=True, extra_compile_args=SAME_ARITHMETIC),
    Extension("galileo_cnc.plan.ink._edge_index", ["galileo_cnc/plan/ink/edge_index.c"],
              optional=True, extra_compile_args=SAME_ARITHMETIC),
])
