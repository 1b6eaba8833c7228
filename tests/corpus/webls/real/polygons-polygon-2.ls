stemsize=0.01
derivation length: 12
axiom: &(-90)[X(36)A/(72)[X(36)B]
p1: A -> [&FA{.].
p2: B  ->  B&.F.}
p3: X(a) -> X(a+4.5)
