delta=30
stemsize= 0.01
derivation length: 4
axiom: L
p1: L -> {-FX+X+FX-|-FX+X+FX}
p2: X -> FX
