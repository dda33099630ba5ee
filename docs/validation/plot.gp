# The validation charts of docs/validation.md from the tables beside this script:
#   cd docs/validation && gnuplot plot.gp
# θ_c against α with the supplement's arccos α (its Fig. 7E), and GSI = cos θ_c against α with
# GSI = α (Fig. 7F/G), both dashed.
set terminal pngcairo size 800,560 enhanced font 'DejaVu Sans,11'
set key bottom left box opaque
set grid
set xrange [0:1]
set xlabel 'α = relative cell–cell tension (1 − w/γ)'
set samples 200

set output 'theta-c.png'
set ylabel 'contact angle θ_c (°)'
set yrange [0:95]
set title 'Contact angle against α'
plot acos(x)*180/pi w l dt 2 lw 2 lc rgb '#444444' title 'arccos α (supplement)', \
     'doublets.dat' u 1:2 w p pt 7 ps 1.6 lc rgb '#1f77b4' title 'passive doublets (320 triangles, standard)', \
     'spheroids-passive.dat' u 1:2 w p pt 5 ps 1.6 lc rgb '#2ca02c' title 'passive spheroids N = 20, surface angle', \
     'spheroids-motile.dat' u 1:2:3 w yerrorbars pt 9 ps 1.6 lc rgb '#d62728' title 'motile spheroids N = 20, 30 (3 seeds; mean ± sd)'

set output 'gsi.png'
set ylabel 'GSI = cos θ_c'
set yrange [0:1.05]
set key top left box opaque
set title 'Geometric surface index against α'
plot x w l dt 2 lw 2 lc rgb '#444444' title 'GSI = α (supplement)', \
     'doublets.dat' u 1:(cos($2*pi/180)) w p pt 7 ps 1.6 lc rgb '#1f77b4' title 'passive doublets', \
     'spheroids-passive.dat' u 1:(cos($2*pi/180)) w p pt 5 ps 1.6 lc rgb '#2ca02c' title 'passive spheroids N = 20', \
     'spheroids-motile.dat' u 1:(cos($2*pi/180)) w p pt 9 ps 1.6 lc rgb '#d62728' title 'motile spheroids N = 20, 30 (mean)'
