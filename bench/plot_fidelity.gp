# e2 against triangle count for one fidelity_bench CSV
# (method,model,kind,triangles,e1,e2,closed,manifold), one PNG.
#   gnuplot -e "csv='DIR/easy3d_building.csv'; png='DIR/easy3d_building.png'; name='easy3d_building'" \
#           bench/plot_fidelity.gp
# Series present in the CSV are drawn: ours, meshopt, cgal_gh (in the order of
# our models, coarse to fine) and peer models (model = -1, one point each).
if (!exists("csv")) { print "plot_fidelity.gp: set csv='FILE.csv'"; exit status 2 }
if (!exists("png")) png = csv[1:strlen(csv) - 4] . ".png"
if (!exists("name")) name = csv

rows(m) = int(system(sprintf("grep -c '^%s,' '%s' || true", m, csv)))
sel(m) = sprintf("'< grep \"^%s,\" \"%s\"'", m, csv)
peers = system(sprintf("awk -F, 'NR > 1 && $2 == -1 { print $1 }' '%s'", csv))

set terminal pngcairo size 900,600 enhanced font "sans,11"
set output png
set datafile separator ","
set title sprintf("%s: e2 against size (fidelity_bench)", name) noenhanced
set xlabel "triangles (log scale)"
set ylabel "e2 = RMSE input -> model (% of bbox diagonal, log scale)"
set logscale xy
set grid xtics ytics mxtics mytics lc rgb "#dddddd"
set key top right box opaque noenhanced

cmd = ""
if (rows("ours") > 0) cmd = cmd . sel("ours") . " using 4:6 with linespoints lw 2 pt 7 ps 1.0 lc rgb '#1f77b4' title 'ours (LOD-Tree candidates)', "
if (rows("meshopt") > 0) cmd = cmd . sel("meshopt") . " using 4:6 with linespoints lw 1.5 pt 5 ps 0.8 lc rgb '#ff7f0e' title 'meshopt QEM (meshopt_simplify)', "
if (rows("cgal_gh") > 0) cmd = cmd . sel("cgal_gh") . " using 4:6 with linespoints lw 1.5 pt 9 ps 0.9 lc rgb '#2ca02c' title 'CGAL Garland-Heckbert', "
do for [p in peers] {
  cmd = cmd . sel(p) . " using 4:6 with points pt 13 ps 2.5 lc rgb '#d62728' title '" . p . " (peer model)', "
}
if (strlen(cmd) == 0) { print "plot_fidelity.gp: no rows in " . csv; exit status 1 }
eval "plot " . cmd[1:strlen(cmd) - 2]
