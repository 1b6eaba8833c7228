n=5; delta=22.5; stemsize=0.1
axiom: X
p0: X->F-[[X]+X]+F[+FX]-X
p1: F->FF

