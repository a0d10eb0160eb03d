#!/usr/bin/env bash
# penumbra against POV-Ray 3.7 on the seed room: both render 1920×1080 with
# an 8×8-sampled area light (penumbra: 64 grid shadow rays), trace depth 4,
# no anti-aliasing, on 2 threads; each is run RUNS times and the medians of
# the wall and CPU times of the whole processes (parse, render, PNG write)
# are compared.
#
#   benches/peers/run.sh            # 3 runs each
#   RUNS=5 WIDTH=960 HEIGHT=540 benches/peers/run.sh
#   PENUMBRA=/path/to/penumbra benches/peers/run.sh   # no cargo build
#
# Images and logs go to target/peers/; compare them with
#   penumbra compare target/peers/penumbra.png target/peers/povray.png
set -euo pipefail
cd "$(dirname "$0")/../.."
RUNS=${RUNS:-3}
WIDTH=${WIDTH:-1920}
HEIGHT=${HEIGHT:-1080}
THREADS=${THREADS:-2}
OUT=target/peers
mkdir -p "$OUT"

if ! command -v povray >/dev/null || [ ! -x /usr/bin/time ]; then
    echo "installing povray and time (Debian packages)" >&2
    if [ "$(id -u)" -eq 0 ]; then apt-get install -y povray time; else sudo apt-get install -y povray time; fi
fi
# PENUMBRA=path/to/binary skips the build (e.g. to time a saved binary).
if [ -z "${PENUMBRA:-}" ]; then
    cargo build --release --quiet
    PENUMBRA=target/release/penumbra
fi

# "wall cpu" seconds of a command (cpu = user + system of all its
# threads), its output appended to a log. On a machine shared with other
# work the CPU time varies far less than the wall time.
measure() {
    local log=$1; shift
    local t
    t=$(mktemp)
    /usr/bin/time -f '%e %U %S' -o "$t" "$@" >>"$log" 2>&1
    awk '{ print $1, $2 + $3 }' "$t"
    rm -f "$t"
}
median() { sort -g | awk '{ v[NR] = $1 } END { if (NR % 2) print v[(NR + 1) / 2]; else print (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }

echo "load average before: $(cut -d' ' -f1-3 /proc/loadavg)"
: >"$OUT/penumbra.log"
: >"$OUT/povray.log"
pen_wall=(); pen_cpu=(); pov_wall=(); pov_cpu=()
for i in $(seq "$RUNS"); do
    # Alternate the two so that a change in the machine's load hits both.
    read -r w c < <(measure "$OUT/penumbra.log" "$PENUMBRA" render scenes/seed-room.json \
        --width "$WIDTH" --height "$HEIGHT" --shadow-rays 64 --sampling grid --depth 4 \
        --threads "$THREADS" -o "$OUT/penumbra.png")
    pen_wall+=("$w"); pen_cpu+=("$c")
    read -r w c < <(measure "$OUT/povray.log" povray +Ibenches/peers/seed-room.pov \
        +O"$OUT/povray.png" +W"$WIDTH" +H"$HEIGHT" -A +WT"$THREADS" -D +FN)
    pov_wall+=("$w"); pov_cpu+=("$c")
    echo "run $i: penumbra ${pen_wall[-1]} s wall, ${pen_cpu[-1]} s CPU; povray ${pov_wall[-1]} s wall, ${pov_cpu[-1]} s CPU"
done
echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)"

med() { printf '%s\n' "$@" | median; }
ratio() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.1f", a / b }'; }
pw=$(med "${pen_wall[@]}"); pc=$(med "${pen_cpu[@]}")
vw=$(med "${pov_wall[@]}"); vc=$(med "${pov_cpu[@]}")
echo "medians of $RUNS runs at ${WIDTH}x${HEIGHT} on $THREADS threads:"
echo "  wall: penumbra $pw s, povray $vw s: penumbra $(ratio "$vw" "$pw")x faster (goal >= 50x)"
echo "  CPU:  penumbra $pc s, povray $vc s: penumbra $(ratio "$vc" "$pc")x less CPU time"
echo "penumbra's own timing (render only):"
grep -E '^[0-9]+×[0-9]+ in' "$OUT/penumbra.log" | tail -n "$RUNS" | sed 's/^/  /'
echo "POV-Ray's own timing:"
grep -A1 'Trace Time' "$OUT/povray.log" | grep -v '^--' | tail -n $((2 * RUNS)) | sed 's/^/  /'
"$PENUMBRA" compare "$OUT/penumbra.png" "$OUT/povray.png" --diff "$OUT/diff.png" | sed 's/^/  penumbra vs povray: /'
