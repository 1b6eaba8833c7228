delta=30
stemsize= 0.01
derivation length: 4
axiom: L
p1: L -> {C(60)-FC(60)X(1)+X(1)+FC(60)X(1)-|-FC(60)X(1)+X(1)+FC(60)X(1)}
p2: X(n) -> FC(90+2*n)X(n+1)
p3: C(n) -> [;(n)@O(0.1)]
/* p3: C(n) -> */