# Mean absolute error of each warp model against the horizon, from warp-eval's CSV (the rows of
# trajectory "all"); the legend gives each model's mean time per output pixel.
#   gnuplot -e "csv='warp_eval.csv'; out='warp_eval.png'" sim/plots/warp_eval.gp
if (!exists("csv") || !exists("out")) {
    print "warp_eval.gp: set csv='warp_eval.csv' and out='plot.png' with -e"
    exit status 2
}
if (!exists("title")) title = "Warp error against horizon (all trajectories)"

set datafile separator ","
set terminal pngcairo size 800,500 noenhanced font ",10"
set output out
set title title
set xlabel "horizon k (fields of 1001/60000 s)"
set ylabel "mean absolute error, % of full scale"
set logscale y
set grid
set key outside right top
set xtics 1

models = "poly affine homography depth auto hold"
# A model's cell of the "all" rows, NaN elsewhere (gnuplot skips NaN points).
cell(m, col) = (strcol(1) eq "all" && strcol(2) eq m) ? column(col) : NaN

array ns[words(models)]
do for [i = 1:words(models)] {
    m = word(models, i)
    stats csv using (cell(m, 6)) skip 1 nooutput
    ns[i] = STATS_records > 0 ? STATS_mean : NaN
}
plot for [i = 1:words(models)] csv using (cell(word(models, i), 3)):(cell(word(models, i), 5)) \
     skip 1 with linespoints lw 2 pt 7 ps 0.8 \
     title sprintf("%s  %.2f ns/px", word(models, i), ns[i])
