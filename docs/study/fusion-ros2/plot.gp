# θ(t) of the reduced fusion (2 × 30 cells, 30 min) for the schemes of fusion-ros2.md against
# the reference (contact-implicit, Δt 0.1 s, ε_CG 1e-6). Run: cd docs/study/fusion-ros2 && gnuplot plot.gp
set terminal pngcairo size 1100,650 enhanced font 'DejaVu Sans,11'
set output 'theta.png'
set datafile separator ','
set key autotitle columnhead
set title 'Reduced fusion (2 × 30 cells), one seed: fusion angle θ(t) per scheme' noenhanced
set xlabel 'simulated time (min)'
set ylabel 'θ (°)'
set grid
set key bottom right noenhanced
col = 8  # theta_deg
plot 'runs/reference/samples.csv' using ($1/60):col with lines lw 3 lc rgb '#000000' title 'reference (contact-implicit, Δt 0.1 s, ε_CG 1e-6)', \
     'runs/standard/samples.csv' using ($1/60):col with lines lw 1.5 lc rgb '#7f7f7f' title 'standard (Δt 0.1 s): 0.87° RMS', \
     'runs/draft/samples.csv' using ($1/60):col with lines lw 1.5 lc rgb '#1f77b4' title 'contact-implicit Δt 0.5 s: 3.80° RMS', \
     'runs/dt-1/samples.csv' using ($1/60):col with lines lw 1.5 dt 2 lc rgb '#1f77b4' title 'contact-implicit Δt 1 s: 4.82° RMS', \
     'runs/ros2/samples.csv' using ($1/60):col with lines lw 1.5 lc rgb '#ff7f0e' title 'ros2 Δt 0.5 s: 1.89° RMS', \
     'runs/ros2-ic/samples.csv' using ($1/60):col with lines lw 1.5 dt 3 lc rgb '#d62728' title 'ros2 Δt 0.5 s, incomplete Cholesky: 2.15° RMS', \
     'runs/ros2-dt-1/samples.csv' using ($1/60):col with lines lw 1.5 dt 2 lc rgb '#ff7f0e' title 'ros2 Δt 1 s: 2.08° RMS', \
     'runs/kab-0.25/samples.csv' using ($1/60):col with lines lw 1.5 lc rgb '#17becf' title 'contact-implicit Δt 0.5 s, k_AB / 4: 1.77° RMS'
