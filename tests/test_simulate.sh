#!/usr/bin/env bash
# test_simulate.sh IPS: end to end through the ips binary: `ips simulate` (the simulated bench and
# the paper's scan procedure) then `ips fit`, against the scene's truth (--truth) and against
# `ips box`. Asserts: the full procedure on the paperlike scene centres within 0.1 um and focuses
# within the depth tolerance from its random start, and the fit recovers the true 7 x 7 map with
# an rms error below 0.03 (mean-1 normalised) with the dips at the top, left and bottom edges and
# none on the right; the same for the paper's direct 9 x 9 grid; a 7 x 7 map file simulated
# without noise is recovered exactly; noiseless uniform signals equal `ips box`; --offset and
# --pixel mean what they say; `ips fit --fit-geometry` recovers --offset and --radius (against
# --written-radius) within 3 sigma and finds no offset where there is none; bad input exits 2
# with one line on stderr.
set -euo pipefail
ips=$1
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
pass=0
fail=0

ok() { pass=$((pass + 1)); }
bad() { echo "FAIL: $*" >&2; fail=$((fail + 1)); }

# The checks on JSON files, in Python (standard library only). Prints what it finds.
cat >"$tmp/check.py" <<'EOF'
import json, math, sys

def load(p):
    with open(p) as f:
        return json.load(f)

def fit_map(fit, r=7):
    return [f for f in fit["fits"] if f["r"] == r][0]["S"]

def rms(a, b):
    return math.sqrt(sum((x - y) ** 2 for x, y in zip(a, b)) / len(a))

def edges(S, r=7):
    """Mean of each edge (corners left out) and of the interior, for an r x r map, y downward."""
    inner = range(1, r - 1)
    top = sum(S[i] for i in inner) / (r - 2)
    bottom = sum(S[(r - 1) * r + i] for i in inner) / (r - 2)
    left = sum(S[j * r] for j in inner) / (r - 2)
    right = sum(S[j * r + r - 1] for j in inner) / (r - 2)
    mid = sum(S[j * r + i] for j in inner for i in inner) / (r - 2) ** 2
    return top, left, bottom, right, mid

def check_map(what, fit_path, truth_path, limit):
    S = fit_map(load(fit_path))
    T = [m for m in load(truth_path)["maps"] if m["r"] == 7][0]["S_normalised"]
    e = rms(S, T)
    top, left, bottom, right, mid = edges(S)
    print(f"{what}: rms {e:.4f} (limit {limit}); edges top {top:.3f} left {left:.3f} "
          f"bottom {bottom:.3f} right {right:.3f}, interior {mid:.3f}")
    ok = e < limit
    ok &= all(mid - x > 0.08 for x in (top, left, bottom))   # the three dipped edges
    ok &= abs(right - mid) < 0.06                             # no dip on the right
    return ok

def main():
    cmd = sys.argv[1]
    if cmd == "map":
        return check_map(sys.argv[2], sys.argv[3], sys.argv[4], float(sys.argv[5]))
    if cmd == "setup":
        s = load(sys.argv[2])["setup"]
        ex, ey = s["centre_error_um"]
        print(f"setup: centre off by ({ex:+.4f}, {ey:+.4f}) um, focus by "
              f"{s['focus_error_um']:+.4f} um (tolerance {s['focus_tolerance_um']:.3f})")
        return abs(ex) < 0.1 and abs(ey) < 0.1 and abs(s["focus_error_um"]) < s["focus_tolerance_um"]
    if cmd == "points":
        return load(sys.argv[2])["points"] == int(sys.argv[3])
    if cmd == "mapfile":   # write the truth's raw r = 7 map as a map file
        m = [m for m in load(sys.argv[2])["maps"] if m["r"] == 7][0]
        with open(sys.argv[3], "w") as f:
            json.dump({"r": 7, "S": m["S"]}, f)
        return True
    if cmd == "exact":     # the fit of a noiseless 7 x 7 scene against that map
        S = fit_map(load(sys.argv[2]))
        T = [m for m in load(sys.argv[3])["maps"] if m["r"] == 7][0]["S_normalised"]
        e = max(abs(x - y) for x, y in zip(S, T))
        print(f"7 x 7 map file, noiseless: largest error {e:.2e}")
        return e < 1e-4
    if cmd == "signal":    # scan point k's signal against a value
        sc = load(sys.argv[2])
        k, want = int(sys.argv[3]), float(sys.argv[4])
        got = sc["signal_dn"][k]
        print(f"point {k} at ({sc['x_um'][k]:.3f}, {sc['y_um'][k]:.3f}): {got:.9f} DN, "
              f"want {want:.9f}")
        return abs(got - want) <= 1e-6 * abs(want)
    if cmd == "inside":    # every position strictly inside the pixel
        sc = load(sys.argv[2])
        return all(0 < v < sc["pitch_um"] for v in sc["x_um"] + sc["y_um"])
    return False

sys.exit(0 if main() else 1)
EOF
check() { if python3 "$tmp/check.py" "$@"; then ok; else bad "check $*"; fi; }

# 1. The paper's whole procedure on the paperlike scene, then the fit.
"$ips" simulate --scene paperlike --seed 1 --truth "$tmp/truth.json" -o "$tmp/proc.json" \
    >"$tmp/proc_summary.json"
check setup "$tmp/proc_summary.json"
check points "$tmp/proc_summary.json" 81
"$ips" fit "$tmp/proc.json" --r 7 >"$tmp/proc_fit.json"
check map "full procedure" "$tmp/proc_fit.json" "$tmp/truth.json" 0.03

# 2. The paper's 9 x 9 grid inside the POI, from the true centre.
"$ips" simulate --scene paperlike --seed 2 --grid 9 -o "$tmp/grid.json" >/dev/null
"$ips" fit "$tmp/grid.json" --r 7 >"$tmp/grid_fit.json"
check map "9 x 9 grid" "$tmp/grid_fit.json" "$tmp/truth.json" 0.03

# 3. A 7 x 7 map file, no noise: the r = 7 fit gets it back.
check mapfile "$tmp/truth.json" "$tmp/map7.json"
"$ips" simulate --scene "map:$tmp/map7.json" --grid 9 --noiseless --truth "$tmp/truth7.json" \
    -o "$tmp/map7_scan.json" >/dev/null
"$ips" fit "$tmp/map7_scan.json" --r 7 >"$tmp/map7_fit.json"
check exact "$tmp/map7_fit.json" "$tmp/truth7.json"

# 4. Noiseless uniform pixel against ips box: signal = B + flux * box / (4 pi / a^2) / G.
"$ips" simulate --scene uniform --grid 9 --noiseless -o "$tmp/uni.json" >/dev/null
"$ips" simulate --scene uniform --grid 9 --noiseless --offset 0.3,-0.2 -o "$tmp/uni_off.json" \
    >/dev/null
R=$(python3 -c 'print(repr(1.22 * 0.55 / (2 * 0.25)))')
want() { # DN of a uniform pixel for a spot at (x, y)
    local v
    v=$("$ips" box "$R" 0 6 0 6 "$1" "$2" | awk 'NR == 1 {print $1}')
    python3 -c "import math; R=$R; a=math.pi*1.2196698912665045/R; \
print(repr(100 + 21500 * $v / (4 * math.pi / a**2) / 3.153))"
}
for k in 0 40 44 80; do
    xy=$(python3 -c "import json; s=json.load(open('$tmp/uni.json')); print(s['x_um'][$k], s['y_um'][$k])")
    read -r x y <<<"$xy"
    check signal "$tmp/uni.json" "$k" "$(want "$x" "$y")"
    # --offset DX,DY: the spot really was at the written position plus the offset
    xo=$(python3 -c "print($x + 0.3)")
    yo=$(python3 -c "print($y - 0.2)")
    check signal "$tmp/uni_off.json" "$k" "$(want "$xo" "$yo")"
done

# 5. --pixel: a neighbour's response from the full procedure, positions inside that pixel.
"$ips" simulate --scene uniform --frames 1 --area 3 --pixel 1,0 -o "$tmp/nb.json" \
    >"$tmp/nb_summary.json"
check points "$tmp/nb_summary.json" 81
check inside "$tmp/nb.json"

# 7. --written-radius and ips fit --fit-geometry: a 4 x 4 map scanned by a spot 1.1x wider than
# written on a grid offset by (-0.3, +0.2) um; the r = 4 geometry fit finds the truth within
# 3 sigma and lowers chi2; with the written geometry true, the offset found is 0 within 3 sigma.
geo() { # geo FIT R DX DY: the geometry of ips fit's JSON against a truth
    python3 - "$@" <<'PY'
import json, sys
g = json.load(open(sys.argv[1]))["geometry"]
R, dx, dy = map(float, sys.argv[2:5])
print("geometry: R %.4f +- %.4f (true %g), dx %.4f +- %.4f (%g), dy %.4f +- %.4f (%g), chi2 %.1f -> %.1f"
      % (g["spot_radius_um"], g["spot_radius_um_err"], R, g["dx_um"], g["dx_um_err"], dx, g["dy_um"],
         g["dy_um_err"], dy, g["chi2_fixed"], g["chi2_fitted"]))
ok = g["status"] == "ok" and g["chi2_fitted"] <= g["chi2_fixed"] and g["r"] == 4
for v, e, t in ((g["spot_radius_um"], g["spot_radius_um_err"], R), (g["dx_um"], g["dx_um_err"], dx),
                (g["dy_um"], g["dy_um_err"], dy)):
    ok &= 0 < e < 0.1 and abs(v - t) < 3 * e
sys.exit(0 if ok else 1)
PY
}
"$ips" simulate --scene paperlike:4 --grid 9 --seed 5 --radius 1.4762 --written-radius 1.342 \
    --offset -0.3,0.2 -o "$tmp/geo.json" >"$tmp/geo_sum.json"
python3 -c "import json, sys; s = json.load(open('$tmp/geo_sum.json')); f = json.load(open('$tmp/geo.json')); \
sys.exit(0 if s['spot_radius_um'] == 1.4762 and f['spot_radius_um'] == 1.342 else 1)" && ok ||
    bad "--written-radius: the file does not say 1.342 um with a true 1.4762 um"
"$ips" fit "$tmp/geo.json" --r 4 --sigma shot+read --fit-geometry --geometry-r 4 >"$tmp/geo_fit.json"
geo "$tmp/geo_fit.json" 1.4762 -0.3 0.2 && ok || bad "the geometry fit missed the offset scan's truth"
"$ips" simulate --scene paperlike:4 --grid 9 --seed 6 -o "$tmp/geo0.json" >/dev/null
"$ips" fit "$tmp/geo0.json" --r 4 --sigma shot+read --fit-geometry --geometry-r 4 >"$tmp/geo0_fit.json"
geo "$tmp/geo0_fit.json" 1.342 0 0 && ok || bad "the geometry fit found an offset where none was"
expect_fit_usage() {
    local code=0
    "$ips" fit "$@" >"$tmp/out" 2>"$tmp/err" || code=$?
    if [[ $code -eq 2 && $(wc -l <"$tmp/err") -eq 1 ]]; then ok; else
        bad "ips fit $* gave exit $code: $(cat "$tmp/err")"
    fi
}
expect_fit_usage "$tmp/geo.json" --geometry-r 4
expect_fit_usage "$tmp/geo.json" --fit-geometry --geometry-r 0
expect_fit_usage "$tmp/geo.json" --r 2 --fit-geometry --geometry-r 9 # 84 parameters, 81 points

# 6. Bad input: exit 2, one line on stderr.
expect_usage() {
    local code=0
    "$ips" simulate "$@" >"$tmp/out" 2>"$tmp/err" || code=$?
    if [[ $code -eq 2 && $(wc -l <"$tmp/err") -eq 1 ]]; then ok; else
        bad "ips simulate $* gave exit $code: $(cat "$tmp/err")"
    fi
}
expect_usage --scene paperlike
expect_usage --scene bogus -o "$tmp/x.json"
expect_usage --grid 11 -o "$tmp/x.json"
expect_usage --scene map:/nonexistent/map.json -o "$tmp/x.json"
expect_usage --radius 1.3 --na 0.3 -o "$tmp/x.json"
expect_usage --offset 1 -o "$tmp/x.json"
expect_usage --frames 0 -o "$tmp/x.json"
expect_usage --pixel 9,0 -o "$tmp/x.json"
expect_usage --nope -o "$tmp/x.json"
expect_usage --written-radius 0 -o "$tmp/x.json"
[[ ! -e "$tmp/x.json" ]] && ok || bad "a failed simulate left an output file"

echo "$pass passed, $fail failed"
[[ $fail -eq 0 ]]
