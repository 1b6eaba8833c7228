angle factor: 12 
initial color: 16
color increment: 1
initial line width: 1.3
line width increment: 1.0
viewpoint: 0,0,1
view reference point: 0,0,0
twist: 0
projection: parallel
front distance: -10.0
back distance: 10
scale factor: 0.9
z buffer: on
cue range: 0
shade mode: 3
font: -adobe-helvetica-medium-r-normal-*-24-*-*-*-*-*-*-*
/* polygonization level: 2 */
contour sides: 7
light direction: 1.0,1.0, 3.0
diffuse reflection: 10
tropism direction: 1.0,-3.0,0.0
initial elasticity: 0.000
elasticity increment: 0.0
function: rho.func
curve: profile.con
