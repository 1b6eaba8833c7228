4
25
50
AB      # the axiom
A=+FA
B=-FB
@
