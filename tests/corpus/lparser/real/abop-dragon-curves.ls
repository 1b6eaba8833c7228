# --- L-System Parser/Mutator --- Lj Lapre ----------------------------------
3	# recursion depth
90	# angle
20	# thickness as % of length
X+cX+cX+cX
X=^F+F+F+F+&f
F=F-F+F+FF-F-F+F
@
