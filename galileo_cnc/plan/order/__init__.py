"""Path order: pen paths -> the order they are drawn in (docs/plan.md, "Path order").

`apertures.optimized_order` is the entry the planner calls: a Program's work grouped
one pen per aperture (`apertures.group_by_aperture`), and each pen's paths chained and
ordered to cut pen-up travel (`paths.optimize`: pieces.py, repeats.py, chains.py with
retrace.py, then tour.py's search over nearby.py's queries, compiled from
tour_search.c where it could be built). G-code from elsewhere is reordered only when
asked and only when that is safe (gcode_order.py).
"""
