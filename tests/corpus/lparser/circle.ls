4
25
50
A      # the axiom
A=+FA
@
