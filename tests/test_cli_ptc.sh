#!/bin/bash
# test_cli_ptc.sh IPS: `ips ptc --sim` end to end (docs/contracts.md): the printed gain and read
# noise within 2 % of the sensor the simulator was given (128 x 128 pixels: the relative error of
# one level's variance is sqrt(2/16384) = 1.1 %, the fits over ~30 levels bring it to ~0.3 %),
# the report's shape, and bad input: exit 2 with one line on stderr. python3 standard library.
set -u
IPS=${1:?usage: test_cli_ptc.sh PATH/TO/ips}
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
failures=0

fail() {
    echo "FAIL: $*" >&2
    failures=$((failures + 1))
}

measure() { # G RN: run and check against the truth
    local G=$1 RN=$2
    if ! "$IPS" ptc --sim --roi 128 --gain "$G" --read-noise "$RN" >"$TMP/ptc.json"; then
        fail "ips ptc --sim --gain $G --read-noise $RN exited non-zero"
        return
    fi
    python3 - "$TMP/ptc.json" "$G" "$RN" <<'PY' || fail "ips ptc --gain $G --read-noise $RN"
import json, sys
r = json.load(open(sys.argv[1])); G = float(sys.argv[2]); RN = float(sys.argv[3])
bad = []
if abs(r["gain_e_per_dn"] / G - 1) > 0.02: bad.append(f"gain {r['gain_e_per_dn']} vs {G}")
if abs(r["read_noise_e"] / RN - 1) > 0.02: bad.append(f"read noise {r['read_noise_e']} vs {RN}")
if abs(r["K"] * r["gain_e_per_dn"] - 1) > 1e-12: bad.append("K is not 1 / gain")
b = r["bench"]
if b["gain_e_per_dn"] != G or b["read_noise_e"] != RN or b["pixels"] != 128 * 128:
    bad.append(f"bench {b}")
clip = min(b["full_well_e"], (b["full_scale_dn"] - b["bias_dn"]) * G) / G
if not (0.95 * clip <= r["saturation_dn"] <= clip): bad.append(f"saturation {r['saturation_dn']}")
lv = r["levels"]
if len(lv) != b["levels"] or any(set(l) != {"exposure_us", "mu", "sigma2", "mu_dark",
                                            "sigma2_dark"} for l in lv):
    bad.append("levels table")
if not r["linearity_error_pct"] < 0.1: bad.append(f"linearity {r['linearity_error_pct']}")
print(f"G {G} -> {r['gain_e_per_dn']:.4f}, read noise {RN} -> {r['read_noise_e']:.4f}")
if bad: print("; ".join(bad), file=sys.stderr); sys.exit(1)
PY
}

measure 3.153 5.67
measure 2.0 8.0

bad_input() { # expected message fragment, then the arguments
    local want=$1
    shift
    "$IPS" ptc "$@" >"$TMP/out" 2>"$TMP/err"
    local rc=$?
    local lines
    lines=$(wc -l <"$TMP/err")
    if [ $rc -ne 2 ] || [ "$lines" -ne 1 ] || ! grep -q -- "$want" "$TMP/err"; then
        fail "ips ptc $*: exit $rc, $lines lines: $(cat "$TMP/err")"
    fi
}
bad_input "--sim is required" --gain 3
bad_input "levels" --sim --levels 2
bad_input "gain" --sim --gain abc
bad_input "roi" --sim --roi 300
bad_input "bias" --sim --bias 20000
bad_input "unknown option" --sim --bogus
bad_input "unexpected argument" --sim extra

# noise-free frames have no photon-transfer slope: a failure (1), one line
"$IPS" ptc --sim --roi 16 --levels 5 --noiseless >/dev/null 2>"$TMP/err"
rc=$?
[ $rc -eq 1 ] && [ "$(wc -l <"$TMP/err")" -eq 1 ] || fail "--noiseless: exit $rc, $(cat "$TMP/err")"

"$IPS" ptc --help | grep -q "usage: ips ptc" || fail "ips ptc --help"

if [ $failures -ne 0 ]; then
    echo "$failures failures"
    exit 1
fi
echo "ips ptc: all checks passed"
