"""Program -> Job, in stages (docs/plan.md). `pipeline.plan_file` is the one pipeline
every front end calls: read the file, offset it, ink it (ink mode), order its paths and
plan the machine commands.

Each stage imports only those below it (tests/test_layout.py checks it):

  gcode_writer.py  a planned file as pen-plotter G-code (`galileo-cnc convert`)
  pipeline.py      the stages in turn for one file
  open_traces.py   beside it: the trace pieces an ink plan leaves out, as one summary
  planner.py       ordered rows -> machine commands in steps, soft limits checked
  ink/             beside the planner, neither importing the other: Gerber copper ->
                   pen paths for a pen set (docs/ink.md); it starts path order on its
                   walks' ends while their arcs are fitted
  order/           pen paths -> the order they are drawn in: one pen per aperture,
                   paths chained and ordered to cut pen-up travel
  shared           offsets.py (where the artwork goes), curves.py (arcs as chords),
                   widths.py (an aperture's stroke width), native.py (the compiled
                   parts), collector.py, measure.py (what a planned Job draws),
                   transform.py (--scale, --rotate, --fit), feeds.py (feeds checked)
"""
