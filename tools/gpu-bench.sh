#!/usr/bin/env bash
# The GPU check (issue 16): the runtime on a real GPU against the CPU reference, and `rrskin
# bench` at 1, 256, 4096 and 16384 characters on the CesiumMan and human_heavy models (and
# CesiumMan with 32 pose-space correctives, CesiumMan of 60 and of 240 delta-mush keys, and
# CesiumMan of both kinds of proxy in one palette, trained without a cost budget, for their cost
# on a GPU), each beside the cost model's prediction (`rrskin info --json`'s `cost`, calibrated
# on lavapipe: the run checks how it carries over), into one JSON file. The GPU machine has no network and maybe no Rust, so the work is in two steps:
#
#   tools/gpu-bench.sh prepare [DIR]     here (network, Rust): build, train, download, into DIR
#   tools/gpu-bench.sh run [DIR] [OUT]   there, from the repository root: one run, a few minutes
#
# DIR (default target/gpu-bench, ~60 MiB, an ignored path: hand it to the device's `carry`)
# holds release builds of `rrskin` and of the Vulkan test binaries, the six trained models and
# the Debian packages of the Vulkan loader and the validation layer (docs/gpu-measurement.md:
# unpacked with dpkg -x, then ldconfig). OUT defaults to $OUT/gpu-bench.json when
# $OUT is set (the device's output folder), else DIR/gpu-bench.json. CHARACTERS (default
# "1 256 4096 16384") overrides the crowd sizes, e.g. to try the run on lavapipe; BANDWIDTH
# (GB/s, default 4800: an H200's HBM3e peak) is the peak `rrskin bench --bandwidth` reports the
# fraction of the bandwidth bound against.
set -euo pipefail
cd "$(dirname "$0")/.."
step=${1:-}
dir=${2:-target/gpu-bench}
MODELS="cesiumman human_heavy cesiumman_correctives cesiumman_mush cesiumman_mush240 cesiumman_both"

prepare() {
    mkdir -p "$dir/bin" "$dir/debs"
    cargo build --release -p rrskin-tools
    cp target/release/rrskin "$dir/bin/"
    # The GPU tests, built in release (their validation layer comes with the packages below).
    cargo test --release --no-run --test vulkan --test engine_path --message-format=json \
        | python3 -c 'import json, sys
for line in sys.stdin:
    m = json.loads(line)
    if m.get("reason") == "compiler-artifact" and m.get("executable") and m["target"]["kind"] == ["test"]:
        print(m["target"]["name"], m["executable"])' \
        | while read -r name exe; do cp "$exe" "$dir/bin/test-$name"; done
    target/release/rrskin train data/cesiumman -o "$dir/cesiumman.rrs"
    target/release/rrskin train data/human_heavy -o "$dir/human_heavy.rrs"
    local free=(--budget none)
    target/release/rrskin train data/cesiumman --correctives 32 "${free[@]}" \
        -o "$dir/cesiumman_correctives.rrs"
    target/release/rrskin train data/cesiumman --reduction delta-mush "${free[@]}" \
        -o "$dir/cesiumman_mush.rrs"
    target/release/rrskin train data/cesiumman --reduction delta-mush --proxies 240 \
        "${free[@]}" -o "$dir/cesiumman_mush240.rrs"
    target/release/rrskin train data/cesiumman --reduction both "${free[@]}" \
        -o "$dir/cesiumman_both.rrs"
    (cd "$dir/debs" && apt-get download libvulkan1 libegl1 libglvnd0 libopengl0 libgl1 libglx0 \
        libgles2 vulkan-validationlayers)
    du -sh "$dir"
}

run() {
    local out=${3:-${OUT:+$OUT/gpu-bench.json}}
    out=${out:-$dir/gpu-bench.json}
    local log
    log=$(dirname "$out")/gpu-bench.log
    : >"$log"
    if ! ldconfig -p | grep -q libvulkan.so.1; then
        for deb in "$dir"/debs/*.deb; do dpkg -x "$deb" /; done
        ldconfig
    fi
    local icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
    if [[ -z "${VK_DRIVER_FILES:-}" && -f $icd ]]; then export VK_DRIVER_FILES=$icd; fi
    local tests=()
    for t in "$dir"/bin/test-*; do
        local name=${t##*/test-} status=passed
        # The trained-file check (ignored by default) runs on every trained model.
        if ! "$t" --test-threads 1 >>"$log" 2>&1; then status=failed; fi
        if [[ $name == vulkan ]]; then
            for m in $MODELS; do
                RRSKIN_MODEL="$dir/$m.rrs" "$t" --ignored --test-threads 1 >>"$log" 2>&1 \
                    || status=failed
            done
        fi
        tests+=("\"$name\": \"$status\"")
    done
    local benches=()
    for m in $MODELS; do
        local predicted
        predicted=$("$dir/bin/rrskin" info "$dir/$m.rrs" --json 2>>"$log") || predicted=null
        benches+=("{\"model\": \"$m\", \"info\": $predicted}")
        for c in ${CHARACTERS:-1 256 4096 16384}; do
            local b
            b=$("$dir/bin/rrskin" bench "$dir/$m.rrs" --characters "$c" \
                --bandwidth "${BANDWIDTH:-4800}" --json 2>>"$log") \
                || b="{\"error\": \"see gpu-bench.log\"}"
            benches+=("{\"model\": \"$m\", \"characters\": $c, \"bench\": $b}")
        done
    done
    local joined
    joined=$(IFS=,; echo "${benches[*]}")
    printf '{"tests": {%s}, "benches": [%s]}\n' "$(IFS=,; echo "${tests[*]}")" "$joined" >"$out"
    echo "wrote $out (log: $log)"
    ! grep -q '"failed"' "$out"
}

case $step in
prepare) prepare ;;
run) run "$@" ;;
*)
    echo "usage: tools/gpu-bench.sh prepare [DIR] | run [DIR] [OUT.json]" >&2
    exit 2
    ;;
esac
