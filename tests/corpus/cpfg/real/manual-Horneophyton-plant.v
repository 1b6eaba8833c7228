initial color: 1
viewpoint: 0.3,0.3,1
view reference point: 0,0,0
projection: parallel
front distance: -100
back distance: 100
scale factor: 1.0
z buffer: on
line style: cylinder
render mode: shadows
polygonization level: 3
light: V:400 500 800 


