delta=25.7
stemsize = 0.1
derivation length: 4
axiom: F
p0: F->F[+F]F[-F]F

