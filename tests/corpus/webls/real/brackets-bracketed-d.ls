n=7; delta=20; stemsize=1
axiom: ;(1)X
p0: X->F[;(60)+X]F[;(1)-X]+X
p1: F->FF

