5
30
10
FFL
a=30 # changes leaf angle, broad or thin.
L={-(a)f+(a)f+(a)f-(a)|-(a)f+(a)f}
@
