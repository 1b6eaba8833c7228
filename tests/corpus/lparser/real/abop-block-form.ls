# --- L-System Parser/Mutator --- Lj Lapre ----------------------------------
3	# recursion depth
90	# angle
10	# thickness as % of length
A
A=B-F+CFC+F-D&F^D-F+&&CFC+F+B>>
B=A&F^CFB^F^D^^-F-D^|F^B|FC^F^A>>
C=|D^|F^B-F+C^F^A&&FA&F^C+F+B^F^D>>
D=|CFB-F+B|FA&F^A&&FB-F+B|FC>>
@
