n=7; delta=25.7; stemsize=0.1
axiom: X
p0: X->F[+X][-X]FX
p1: F->FF

