#!/usr/bin/env bash
# The example engine (examples/engine_client/) built against the installed package, run under
# the validation layer with synchronisation validation (any message fails it), and compared
# with `terravt render` on the same flat scene and camera with neutral lighting (image = albedo):
# PSNR >= 50 dB, >= 99.9 % of pixels within 1/255, page tables byte-identical.
#
# The client runs twice: with its default feedback route (terravt compacts the client's feedback
# buffer on the GPU, record_feedback()) and with --cpu-feedback (the client reads it back and
# passes terravt::PageRequest's); both must match terravt render.
#
# Why the tables can be compared byte for byte: both renderers request every pixel's page
# (feedback divisor 1), the camera is still and the geometry flat, so from the first feedback
# on every frame asks for the same pages with the same pixel counts. terravt ranks them the
# same way (coarse first, coverage, age, page id) and hands out cache slots in that order, the
# cache (512 slots) never evicts and the budget (48 pages a frame) drains the queue within a
# few frames: both converge to the same residency with the same slots, whichever frame their
# first feedback arrived in (each reads the newest finished frame's, never waiting).
# Usage: check_engine_client.sh BUILD_DIR SOURCE_DIR TERRAVT_EXE COMPARE_EXE
set -euo pipefail
build=$1
src=$2
terravt=$3
compare=$4
source "$src/tests/package/install_prefix.sh"
tvt_install_prefix "$build"

tvt_build_client "$src/examples/engine_client" "$work/client" -DCMAKE_BUILD_TYPE=Release

scene=$src/tests/package/flat-scene.json
frames=12
x=1000 y=900 z=40 yaw=35 pitch=-38
cat > "$work/camera.json" <<JSON
{"lens": {"vertical_fov_deg": 60, "near_m": 0.5, "far_m": 100000},
 "keys": [{"time_s": 0, "position_m": [$x, $y, $z], "yaw_deg": $yaw, "pitch_deg": $pitch}]}
JSON
size=(--width 256 --height 192)

client() {  # client NAME [FLAGS...]: writes $work/NAME.png and $work/NAME_table.bin
  local name=$1
  shift
  "$work/client/engine_client" --validation --scene "$scene" --extent-m 2048 "${size[@]}" --frames $frames \
    --position $x,$y,$z --yaw-deg $yaw --pitch-deg $pitch --fov-deg 60 --feedback-divisor 1 \
    --out "$work/$name.png" --page-table "$work/${name}_table.bin" "$@"
}
client client
client client_cpu --cpu-feedback

"$terravt" render --scene "$scene" --camera "$work/camera.json" "${size[@]}" --frames $frames --every $frames \
  --lighting none --feedback-divisor 1 --quiet --out "$work/render" --page-table "$work/terravt_table.bin"
last=$(printf 'frame_%05d.png' $((frames - 1)))

if [ -n "${TERRAVT_TEST_OUTPUT_DIR:-}" ]; then
  mkdir -p "$TERRAVT_TEST_OUTPUT_DIR"
  cp "$work/client.png" "$TERRAVT_TEST_OUTPUT_DIR/engine_client.png"
  cp "$work/client_cpu.png" "$TERRAVT_TEST_OUTPUT_DIR/engine_client_cpu_feedback.png"
  cp "$work/render/$last" "$TERRAVT_TEST_OUTPUT_DIR/engine_client_terravt_render.png"
fi
for name in client client_cpu; do
  echo "$name against terravt render:"
  "$compare" "$work/$name.png" "$work/render/$last" "$work/${name}_table.bin" "$work/terravt_table.bin" \
    --min-psnr 50 --min-within 0.999
done
