# Speed against error: frame time and colour error against a supersampled reference for each
# caster and number of rays per pixel, from a CSV with the header levels,rays,ms,mae_pct
# (scripts/results.sh writes it from bench-render's quality section).
#   gnuplot -e "csv='quality.csv'; out='speed_error.png'" sim/plots/speed_error.gp
if (!exists("csv") || !exists("out")) {
    print "speed_error.gp: set csv='quality.csv' and out='plot.png' with -e"
    exit status 2
}
if (!exists("title")) title = "Speed against error"

set datafile separator ","
set terminal pngcairo size 800,500 noenhanced font ",10"
set output out
set title title
set xlabel "frame time, ms (best frame, one thread)"
set ylabel "mean absolute colour error, % of full scale"
set grid
set key top right
set offsets graph 0.05, graph 0.1, graph 0.1, graph 0.1

pick(l, col) = (strcol(1) eq l) ? column(col) : NaN
plot for [l in "0 auto"] csv using (pick(l, 3)):(pick(l, 4)) skip 1 \
         with linespoints lw 2 pt 7 ps 1 title sprintf("levels %s", l), \
     for [l in "0 auto"] csv using (pick(l, 3)):(pick(l, 4)):(sprintf("%d ray%s", $2, $2 > 1 ? "s" : "")) \
         skip 1 with labels offset char 1.5, char 0.8 notitle
