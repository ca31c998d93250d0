#!/usr/bin/env bash
# Strong scaling of every simulator from 1 to 2 MPI ranks (one thread per rank), medians of
# three runs, and what the reductions cost. Needs a build with `--features mpi`:
#   cargo build --release --features mpi && rooms/tools/mpi_scaling.sh target/release/propsim
set -euo pipefail
bin=${1:-target/release/propsim}
root=$(cd "$(dirname "$0")/../.." && pwd)
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_btl_vader_single_copy_mechanism=none
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

median() { sort -g | sed -n 2p; }

declare -A jobs=(
  [render]="render builtin:cornell_box_classic --spp 256 -o $work/r.png"
  [acoustic]="acoustic $root/rooms/bras_cr2/scene.toml --rays 100000 --out $work/a"
  [rf]="rf $root/rooms/street_canyon/scene.toml --rays 20000000 --out $work/f"
  [run]="run --out $work/run"
)
printf "%-9s %9s %9s %11s  %s\n" job "1 rank s" "2 ranks s" efficiency "rank 0 at 2 ranks: wait / reduce"
for job in render acoustic rf run; do
  for n in 1 2; do
    for k in 1 2 3; do
      start=$(date +%s.%N)
      mpirun -n "$n" --bind-to core "$bin" --threads 1 ${jobs[$job]} >/dev/null 2>"$work/err"
      echo "$(date +%s.%N) - $start" | bc
      [ "$n" = 2 ] && grep '^mpi:' "$work/err" >>"$work/mpi_$job" || true
    done | median >"$work/t_${job}_$n"
  done
  t1=$(cat "$work/t_${job}_1"); t2=$(cat "$work/t_${job}_2")
  eff=$(echo "scale=3; $t1 / (2 * $t2)" | bc)
  printf "%-9s %9.2f %9.2f %10.1f%%  %s\n" "$job" "$t1" "$t2" "$(echo "$eff * 100" | bc)" "$(tail -1 "$work/mpi_$job" | sed 's/.*waited //')"
done
