#!/usr/bin/env bash
# Runs the real viewer window under Xvfb (no display or GPU needed: Mesa's
# software OpenGL) and saves a screenshot of the whole screen.
#
#   scripts/screenshot.sh [OUT.png] [-- VIEWER ARGS...]
#
# Default output: assets/screenshot.png; default viewer: the seed room.
# WAIT=seconds to let the render finish before the shot (default 12).
set -euo pipefail
cd "$(dirname "$0")/.."

out=assets/screenshot.png
if [[ $# -gt 0 && $1 != -- ]]; then out=$1; shift; fi
[[ ${1:-} == -- ]] && shift
wait_s=${WAIT:-12}

need=()
command -v xvfb-run >/dev/null || need+=(xvfb xauth)
command -v import >/dev/null || need+=(imagemagick)
dpkg -s libgl1-mesa-dri libegl1 libxkbcommon-x11-0 >/dev/null 2>&1 \
    || need+=(libgl1-mesa-dri libegl1 libxkbcommon-x11-0)
if [[ ${#need[@]} -gt 0 ]]; then
    sudo=; [[ $(id -u) -ne 0 ]] && sudo=sudo
    $sudo apt-get update -qq
    $sudo apt-get install -y --no-install-recommends "${need[@]}"
fi

cargo build --release --quiet
bin=$PWD/target/release/penumbra
mkdir -p "$(dirname "$out")"
[[ $out == /* ]] || out=$PWD/$out
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# Inside the X server: start the viewer, wait, grab the screen, close it.
cat >"$tmp/inner.sh" <<'INNER'
#!/usr/bin/env bash
set -u
out=$1 wait_s=$2 bin=$3; shift 3
"$bin" view "$@" &
pid=$!
sleep "$wait_s"
if ! kill -0 "$pid" 2>/dev/null; then
    echo "screenshot.sh: the viewer exited early" >&2
    wait "$pid"; exit 1
fi
# No window manager: the window sits at the top-left at its default size.
import -window root -crop 1500x860+0+0 +repage "$out"
kill "$pid"; wait "$pid" 2>/dev/null || true
INNER
chmod +x "$tmp/inner.sh"

# Software rendering: no GPU on CI or in containers.
LIBGL_ALWAYS_SOFTWARE=1 xvfb-run -a -s "-screen 0 1600x900x24" \
    "$tmp/inner.sh" "$out" "$wait_s" "$bin" "$@"
echo "wrote $out"
