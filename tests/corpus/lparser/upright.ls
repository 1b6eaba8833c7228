2      # recursion depth
25     # angle
50     # thickness as % of length
F      # draw a full length
@      # end of file mark
