angle factor: 24 
initial color: 127
color increment: 1
initial line width: 0.5
line width increment: 1.0
viewpoint: 0,0,30
view reference point: 0,0,0
twist: 0
projection: parallel
front distance: -1000.0
back distance: 1000.0
scale factor: 0.95
z buffer: on
cue range: 0
shade mode: 3
light direction: 1.0,0.0,0.5
diffuse reflection: 30
tropism direction: 0.2,1.0,0.0
initial elasticity: 0.02
elasticity increment: 0.0
surface ambient: .15
surface diffuse: .85
line: L line.s .01
surface: f female.s 1.5 3 3
surface: b bract.s 1.5 3 3
surface: n nmale.s 1.5 3 3
surface: c chaff.s 1.2 3 3
