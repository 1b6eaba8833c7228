n=5; delta=20
stemsize=0.1
derivation length: 5
axiom: F
p0: F->F[+F]F[-F][F]

