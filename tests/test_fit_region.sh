#!/bin/bash
# test_fit_region.sh IPS: `ips fit --region` and the whole-raster Wiener baseline end to end, run
# from tests/data. A uniform scene is simulated with every point of the 51 x 51 raster
# (`ips simulate --all-points`); the points each region must keep are counted here from the file
# itself (fit/region.h's rule: strictly inside (0, pitch)^2, or within the margin, 1e-6 pitch
# tolerance), and the Wiener map must be the raster's nodes strictly inside the pixel. Bad values
# exit 2 with one line on stderr. Uses python3 with its standard library only.
set -u
IPS=${1:?usage: test_fit_region.sh PATH/TO/ips}
REF=paperlike_scan.json
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
failures=0
checks=0

fail() {
    echo "FAIL: $*" >&2
    failures=$((failures + 1))
}

# expect_bad PATTERN ARGS...: exit 2, nothing on stdout, one stderr line containing PATTERN
expect_bad() {
    local pattern=$1
    shift
    checks=$((checks + 1))
    "$IPS" "$@" >"$TMP/out" 2>"$TMP/err"
    local rc=$? lines
    lines=$(wc -l <"$TMP/err")
    if [ "$rc" -ne 2 ]; then fail "ips $* exited $rc, want 2"; fi
    if [ "$lines" -ne 1 ]; then fail "ips $* wrote $lines lines on stderr, want 1"; fi
    if ! grep -qF -- "$pattern" "$TMP/err"; then
        fail "ips $*: stderr '$(head -c 300 "$TMP/err")' does not contain '$pattern'"
    fi
    if [ -s "$TMP/out" ]; then fail "ips $* wrote to stdout on bad input"; fi
}

# ---- bad values ----
expect_bad "region must be inside, all or margin (got 'outside')" fit $REF --region outside
expect_bad "--region margin needs a distance in um after it (got nothing)" fit $REF --region margin
expect_bad "--region margin needs a distance in um after it (got 'wide')" fit $REF --region margin wide
expect_bad "region margin must be between 0 and 1000 um (got -1)" fit $REF --region margin -1
expect_bad "--region needs a value" fit $REF --region
expect_bad "--wiener-nsr must be spectral, white or a number > 0 (got 'loud')" fit $REF --wiener --wiener-nsr loud
expect_bad "--wiener-nsr must be spectral, white or a number > 0 (got '0')" fit $REF --wiener --wiener-nsr 0
expect_bad "--wiener-nsr needs --wiener" fit $REF --wiener-nsr white
expect_bad "--all-points needs the full procedure" simulate --grid 9 --all-points -o "$TMP/x.json"

# ---- a file whose points are all inside: every region fits the same points ----
checks=$((checks + 1))
for rg in "inside" "all" "margin 0"; do
    "$IPS" fit $REF --r 3 --region $rg >"$TMP/ref_${rg// /_}.json" 2>"$TMP/err" ||
        fail "ips fit --region $rg: $(cat "$TMP/err")"
done
python3 - "$TMP" <<'EOF' || fail "regions on the reference scan"
import json, sys
t = sys.argv[1]
docs = {k: json.load(open(f"{t}/ref_{k}.json")) for k in ("inside", "all", "margin_0")}
bad = []
for k, d in docs.items():
    if d["n_points"] != 81 or d["n_raster"] != 81: bad.append(f"{k}: n_points {d['n_points']}")
    if d["fits"][0]["chi2"] != docs["inside"]["fits"][0]["chi2"]: bad.append(f"{k}: chi2")
if docs["inside"]["region"] != "inside" or docs["inside"]["margin_um"] is not None: bad.append("inside")
if docs["margin_0"]["region"] != "margin" or docs["margin_0"]["margin_um"] != 0: bad.append("margin")
if docs["all"]["region"] != "all": bad.append("all")
for b in bad: print(b)
sys.exit(1 if bad else 0)
EOF

# ---- the whole raster: regions select by the rule, Wiener is cropped to the pixel ----
checks=$((checks + 1))
if "$IPS" simulate --scene uniform --all-points --seed 3 -o "$TMP/all.json" >/dev/null 2>"$TMP/err"; then
    for rg in "inside" "margin 1.34" "all"; do
        "$IPS" fit "$TMP/all.json" --r 2 --wiener --region $rg >"$TMP/all_${rg// /_}.json" \
            2>"$TMP/err" || fail "ips fit all points --region $rg: $(cat "$TMP/err")"
    done
    python3 - "$TMP" <<'EOF' || fail "regions on the whole raster"
import json, sys
t = sys.argv[1]
scan = json.load(open(f"{t}/all.json"))
p, xs, ys = scan["pitch_um"], scan["x_um"], scan["y_um"]
eps = 1e-6 * p
def inside(v): return eps < v < p - eps
def within(v, m): return -m - eps <= v <= p + m + eps
want = {"inside": sum(inside(x) and inside(y) for x, y in zip(xs, ys)),
        "margin_1.34": sum(within(x, 1.34) and within(y, 1.34) for x, y in zip(xs, ys)),
        "all": len(xs)}
bad = []
if len(xs) != 51 * 51: bad.append(f"{len(xs)} points simulated, want 2601")
if not (min(xs) < 0 and max(xs) > p): bad.append("no points outside the pixel")
nodes = sorted({round(x, 9) for x in xs if inside(x)})
for k, n in want.items():
    d = json.load(open(f"{t}/all_{k}.json"))
    if d["n_points"] != n: bad.append(f"{k}: n_points {d['n_points']}, want {n}")
    if d["n_raster"] != len(xs): bad.append(f"{k}: n_raster {d['n_raster']}")
    w = d["wiener"]
    if w["raster"] != [51, 51] or not w["cropped"] or w["region"] != "all":
        bad.append(f"{k}: wiener raster {w['raster']} cropped {w['cropped']}")
    if w["nx"] != len(nodes) or w["ny"] != len(nodes) or len(w["S"]) != len(nodes) ** 2:
        bad.append(f"{k}: wiener {w['nx']} x {w['ny']}, want {len(nodes)} nodes a side")
    if abs(w["x0_um"] - nodes[0]) > 1e-6: bad.append(f"{k}: wiener x0 {w['x0_um']} vs {nodes[0]}")
    if abs(sum(w["S"]) / len(w["S"]) - 1) > 1e-9: bad.append(f"{k}: wiener mean")
    if w["nsr_method"] != "spectral": bad.append(f"{k}: nsr_method {w['nsr_method']}")
if want["inside"] >= want["margin_1.34"] or want["margin_1.34"] >= want["all"]:
    bad.append(f"regions do not grow: {want}")
for b in bad: print(b)
sys.exit(1 if bad else 0)
EOF
else
    fail "ips simulate --all-points: $(cat "$TMP/err")"
fi

echo "$checks checks, $failures failed"
[ "$failures" -eq 0 ]
