#!/usr/bin/env python3
"""run_follow.py: the part of scripts/run.sh that talks to the running ipsd (standard library
only). Two commands:

  run_follow.py pick BASE SENSOR COL ROW
      prints "SCAN JOB" of a scan of that pixel still queued or running (resumed after a
      restart), "calibrated CALIB SCAN" when the pixel has a current calibration already, or
      "none" (then run.sh queues a new scan);
  run_follow.py follow BASE SCAN JOB SENSOR COL ROW
      prints the scan's progress (every quarter), its end, then its automatic fit's end with the
      recommended r, the reason and where the calibration is, and exits."""
import http.client
import json
import sys
import time
import urllib.parse

ACTIVE = ("queued", "running")


class Api:
    def __init__(self, base):
        self.netloc = urllib.parse.urlparse(base).netloc
        self.conn = None

    def get(self, path):
        """The JSON of GET path, or None when ipsd does not answer (it is stopping)."""
        for _ in range(2):
            try:
                if self.conn is None:
                    self.conn = http.client.HTTPConnection(self.netloc, timeout=30)
                self.conn.request("GET", path)
                r = self.conn.getresponse()
                body = r.read()
                return json.loads(body) if r.status == 200 else {"_status": r.status}
            except (OSError, http.client.HTTPException, ValueError):
                self.conn = None
        return None


def say(line):
    print("run.sh: " + line, flush=True)


def pick(api, sensor, col, row):
    cal = api.get("/api/sensors/%s/pixels/%s/%s/calibration" % (sensor, col, row))
    scans = api.get("/api/scans?sensor=%s&limit=1000" % sensor) or {"items": []}
    mine = [s for s in scans.get("items", []) if (s["poi"]["col"], s["poi"]["row"]) == (int(col), int(row))]
    for s in sorted(mine, key=lambda s: -s["id"]):
        if s["state"] in ACTIVE:
            jobs = api.get("/api/jobs?kind=scan&scan=%d&limit=1" % s["id"]) or {"items": []}
            if jobs.get("items"):
                print(s["id"], jobs["items"][0]["id"])
                return
    if cal and "id" in cal:
        print("calibrated", cal["id"], cal.get("scan_id") or 0)
        return
    print("none")


def wait_job(api, job, label, progress=None):
    """Polls job until it ends; returns its last JSON (None when ipsd went away)."""
    quarter = 0
    while True:
        j = api.get("/api/jobs/%s" % job)
        if j is None or "_status" in j:
            return None
        if j["state"] not in ACTIVE:
            return j
        if progress and j["state"] == "running":
            q = int(j.get("progress", 0) * 4)
            if q > quarter:
                quarter = q
                progress(j)
        time.sleep(1)


def took(j):
    """A job's run time in seconds, from ipsd's own clock (started_ms, finished_ms)."""
    if j.get("started_ms") and j.get("finished_ms"):
        return (j["finished_ms"] - j["started_ms"]) / 1000
    return float("nan")


def follow(api, scan, job, sensor, col, row):

    def scan_progress(j):
        say("scan %s: %d %% (%d points)" % (scan, 100 * j["progress"], j.get("points_done", 0)))

    j = wait_job(api, job, "scan", scan_progress)
    if j is None:
        return
    s = api.get("/api/scans/%s" % scan) or {}
    if j["state"] != "done":
        say("scan %s ended %s%s" % (scan, j["state"], ": " + j["error"] if j.get("error") else ""))
        return
    say("scan %s done: %d points in %.1f s; its automatic fit is queued"
        % (scan, s.get("points_done", 0), took(j)))
    fits = api.get("/api/jobs?kind=fit&scan=%s" % scan) or {"items": []}
    if not fits.get("items"):
        say("no fit job was queued for scan %s" % scan)
        return
    fjob = min(f["id"] for f in fits["items"])
    f = wait_job(api, fjob, "fit")
    if f is None:
        return
    if f["state"] != "done":
        say("the fit of scan %s ended %s%s" % (scan, f["state"], ": " + f["error"] if f.get("error") else ""))
        return
    fit = api.get("/api/fits/%s" % f["fit_id"]) or {}
    res = fit.get("result") or {}
    best = [m for m in res.get("fits", []) if m.get("r") == res.get("recommended_r")]
    status = best[0].get("status", "?") if best else "?"
    say("fit %s done in %.1f s: recommended r = %s (%s), status %s"
        % (f["fit_id"], took(f), res.get("recommended_r"), res.get("recommended_reason", ""), status))
    cal = api.get("/api/sensors/%s/pixels/%s/%s/calibration" % (sensor, col, row)) or {}
    if "id" in cal:
        say("calibration %s of pixel (%s, %s) is current: %s/api/sensors/%s/pixels/%s/%s/calibration"
            % (cal["id"], col, row, "http://" + api.netloc, sensor, col, row))
        say("the dashboard shows it: http://%s/#/fits/%s" % (api.netloc, f["fit_id"]))


def main(argv):
    if len(argv) == 6 and argv[1] == "pick":
        pick(Api(argv[2]), *argv[3:6])
    elif len(argv) == 8 and argv[1] == "follow":
        try:
            follow(Api(argv[2]), *argv[3:8])
        except KeyboardInterrupt:
            pass
    else:
        sys.exit("usage: run_follow.py pick BASE SENSOR COL ROW | follow BASE SCAN JOB SENSOR COL ROW")


if __name__ == "__main__":
    main(sys.argv)
