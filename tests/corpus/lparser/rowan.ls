8
30
10
FFLK
K={-f+f+f-|-f+f}
L=f[+(70)K][-(70)K]L
@
