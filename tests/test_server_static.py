#!/usr/bin/env python3
"""test_server_static.py IPSD: the dashboard's files are cached by browsers. A real
ipsd serves a web directory made here:
  - every file has an ETag, and a request naming it in If-None-Match (alone, in a list, weak, or
    "*") gets 304 with no body and the same ETag; another tag gets 200 with the file;
  - a file changed on disk (new size and mtime) gets a new ETag, and the old one 200 with the new
    bytes;
  - index.html and the modules are "no-cache" (asked again at every load), files under
    node_modules/ (the versioned plotting library) public with a max-age of a year, immutable;
  - the dashboard's index.html loads the plotting library with the version pinned by
    web/package-lock.json in its query, so a new version is a new URL (read here from the files,
    independently of the server);
  - 404 and 403 answers are unchanged (JSON error body)."""
import json
import os
import re

import ipsd_http
from ipsd_http import Ipsd

HERE = os.path.dirname(os.path.abspath(__file__))
YEAR_S = 365 * 24 * 3600


def write(path, text, mtime):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w") as f:
        f.write(text)
    os.utime(path, (mtime, mtime))


def max_age(cc):
    m = re.search(r"max-age=(\d+)", cc or "")
    return int(m.group(1)) if m else None


def test(c, t, argv, daemons):
    web = os.path.join(t, "web")
    index = "<!doctype html><title>ipsd</title>\n"
    write(os.path.join(web, "index.html"), index, 1700000000)
    write(os.path.join(web, "app.js"), "export const x = 1;\n", 1700000001)
    lib = "/*! lib 1.2.3 */ window.Lib = {};\n" * 100
    write(os.path.join(web, "node_modules", "lib", "lib.min.js"), lib, 1700000002)

    d = Ipsd(argv[1], t)
    daemons.append(d)
    d.start("--web", web)

    # ---- ETag and 304 ----
    r = d.get("/")
    c.status(r, 200, "GET / (index.html)")
    c.eq(r.text, index, "index.html's bytes")
    tag = r.headers.get("ETag")
    c.ok(tag and re.fullmatch(r'"[^"]+"', tag), "index.html has a quoted ETag: %r" % tag)
    c.eq(r.headers.get("Cache-Control"), "no-cache", "index.html is revalidated at every load")
    for inm, what in ((tag, "its ETag"), ("\"nope\", " + tag, "a list holding it"),
                      ("W/" + tag, "its weak form"), ("*", "\"*\"")):
        r = d.get("/", headers={"If-None-Match": inm})
        c.status(r, 304, "If-None-Match with %s" % what)
        c.eq(r.body, b"", "a 304 has no body (%s)" % what)
        c.eq(r.headers.get("ETag"), tag, "the 304 names the ETag (%s)" % what)
        c.eq(r.headers.get("Cache-Control"), "no-cache", "the 304 keeps Cache-Control")
    r = d.get("/index.html", headers={"If-None-Match": tag})
    c.status(r, 304, "/index.html is the same file as /")
    r = d.get("/", headers={"If-None-Match": '"something-else"'})
    c.status(r, 200, "another ETag gets the file")
    c.eq(r.text, index, "with its bytes")

    r = d.get("/app.js")
    c.status(r, 200, "a module")
    c.eq(r.headers.get("Cache-Control"), "no-cache", "a module is revalidated at every load")
    js_tag = r.headers.get("ETag")
    c.ok(js_tag and js_tag != tag, "each file has its own ETag")
    c.status(d.get("/web/app.js", headers={"If-None-Match": js_tag}), 304, "/web/app.js: 304")

    # a change on disk: a new ETag, and the old one gets the new bytes
    write(os.path.join(web, "app.js"), "export const x = 22;\n", 1700000100)
    r = d.get("/app.js", headers={"If-None-Match": js_tag})
    c.status(r, 200, "a changed file: the old ETag gets 200")
    c.eq(r.text, "export const x = 22;\n", "with the new bytes")
    c.ok(r.headers.get("ETag") not in (None, js_tag), "and a new ETag")

    # ---- the versioned library: cached for a year ----
    r = d.get("/node_modules/lib/lib.min.js")
    c.status(r, 200, "a file under node_modules/")
    c.eq(r.text, lib, "its bytes")
    cc = r.headers.get("Cache-Control") or ""
    c.ok("public" in cc and "immutable" in cc and max_age(cc) == YEAR_S,
         "node_modules/ files are cached for a year: %r" % cc)
    r = d.get("/node_modules/lib/lib.min.js", headers={"If-None-Match": r.headers.get("ETag")})
    c.status(r, 304, "and revalidate to 304")
    c.eq(r.body, b"", "with no body")

    # ---- errors stay errors, without caching headers ----
    c.error(d.get("/nothing.js"), 404, "", "an unknown file")
    c.error(d.get("/../etc/passwd"), 404, "", "a path out of the directory")
    c.eq(d.get("/nothing.js").headers.get("ETag"), None, "a 404 has no ETag")
    c.eq(d.stop_term(), 0, "SIGTERM: exit 0")

    # ---- the dashboard loads the library by its pinned version ----
    with open(os.path.join(HERE, "..", "web", "package-lock.json")) as f:
        lock = json.load(f)
    version = lock["packages"]["node_modules/plotly.js-dist-min"]["version"]
    with open(os.path.join(HERE, "..", "web", "index.html")) as f:
        html = f.read()
    srcs = re.findall(r'src="(node_modules/[^"]+)"', html)
    c.ok(srcs and all(s.endswith("?v=" + version) for s in srcs),
         "index.html loads node_modules/ files with ?v=%s (package-lock.json): %r"
         % (version, srcs))


if __name__ == "__main__":
    import sys
    sys.exit(ipsd_http.main(test, sys.argv))
