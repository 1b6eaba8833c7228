# --- L-System Parser/Mutator --- Lj Lapre ----------------------------------
2	# recursion depth
90	# angle
20	# thickness as % of length
X+cX+cX+cX
X=^F+F+F+F+&f
F=F+f-FF+F+FF+Ff+FF-f+FF-F-FF-Ff-FFF
f=ffff
@
