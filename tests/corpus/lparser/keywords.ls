# the keyword layout: each setting named
recursion 5
angle 22.5
thickness 20
axiom F
rule F = "F[+!F][-!F]F
