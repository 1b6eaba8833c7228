#define R 1.456
#define a 85
derivation length: 6
axiom: !(1)F(200)A(100)
p1: A(s) : s >= 1 -> F(s)[+(a)A(s/R)][-(a)A(s/R)]
