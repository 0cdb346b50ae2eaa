"""The Program: the op table every reader produces and the planner consumes, with
its geometry and extents.
"""
