# --- L-System Parser/Mutator --- Lj Lapre ----------------------------------
4	# recursion depth
20	# angle
100	# thickness as % of length
X
X=F[+X]F[-X]+X
F=FF
@
