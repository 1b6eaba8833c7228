delta=5
stemsize=0.01
derivation length: 10
axiom: [A][B]
p1: A -> [+&(delta/2)A{.].C.}
p2: B -> [-&(delta/2)B{.].C}
p3: C -> FC
