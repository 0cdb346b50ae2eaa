(square-and-circle.nc: a 20 mm square with a 10 mm circle inside it)
(galileo-cnc sample drawing; units mm, origin at the lower left corner)
G21 G90 G17
F600
G00 X0 Y0
M03                 ; pen down
G01 X20
Y20
X0
Y0
M05                 ; pen up
G00 X15 Y10
M03
G02 X15 Y10 I-5 J0  ; full circle about (10, 10)
M05
M02
