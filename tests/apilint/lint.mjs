// lint.mjs: runs Redocly's CLI (pinned in tests/apilint/package-lock.json) with its recommended
// rules on the OpenAPI document and fails on any error or warning.
//   node lint.mjs OPENAPI.json [IPSD]
// With IPSD, the document a real ipsd serves (GET /api/openapi.json, which adds the scan request's
// bounds to the file) is linted too: ipsd runs on a free loopback port with a temporary database.
// Exit 77 (skip) when Redocly is not installed (`npm ci --prefix tests/apilint`). Telemetry and
// update checks are off: the suite never reaches the network.
import { spawn, spawnSync } from "node:child_process";
import fs from "node:fs";
import os from "node:os";
import path from "node:path";
import { fileURLToPath } from "node:url";

const here = path.dirname(fileURLToPath(import.meta.url));
const cli = path.join(here, "node_modules", "@redocly", "cli", "bin", "cli.js");
if (!fs.existsSync(cli)) {
    console.log("skip: @redocly/cli not installed (npm ci --prefix tests/apilint)");
    process.exit(77);
}
const [docFile, ipsd] = process.argv.slice(2);
if (!docFile) {
    console.error("usage: node lint.mjs OPENAPI.json [IPSD]");
    process.exit(2);
}

function lint(file, what) {
    const r = spawnSync(process.execPath, [cli, "lint", file, "--extends", "recommended", "--format", "stylish"], {
        encoding: "utf8",
        env: { ...process.env, REDOCLY_TELEMETRY: "off", REDOCLY_SUPPRESS_UPDATE_NOTICE: "true" },
    });
    const out = (r.stdout || "") + (r.stderr || "");
    process.stdout.write(out);
    const problems = out.split("\n").filter((l) => /\b(error|warning)\b\s+[a-z0-9-]+\s/.test(l));
    if (r.status !== 0 || problems.length) {
        console.log(`FAIL: ${what}: Redocly reports ${problems.length} errors and warnings (exit ${r.status})`);
        return false;
    }
    console.log(`${what}: Redocly's recommended rules: no errors, no warnings`);
    return true;
}

async function served(exe) {
    const tmp = fs.mkdtempSync(path.join(os.tmpdir(), "ipsd-lint-"));
    const portFile = path.join(tmp, "port");
    const child = spawn(exe, ["--listen", "127.0.0.1:0", "--port-file", portFile, "--db", path.join(tmp, "ipsd.db"),
                              "--access-log", "off"], { stdio: ["ignore", "ignore", "inherit"] });
    try {
        let port = "";
        for (let i = 0; i < 600 && !port; i++) { // up to 60 s on a busy machine (ASan build)
            if (fs.existsSync(portFile)) port = fs.readFileSync(portFile, "utf8").trim();
            if (!port) await new Promise((res) => setTimeout(res, 100));
        }
        if (!port) throw new Error("ipsd did not start");
        const res = await fetch(`http://127.0.0.1:${port}/api/openapi.json`);
        if (res.status !== 200) throw new Error(`GET /api/openapi.json: ${res.status}`);
        const file = path.join(tmp, "served-openapi.json");
        fs.writeFileSync(file, await res.text());
        return { file, tmp };
    } finally {
        child.kill("SIGTERM");
    }
}

let ok = lint(docFile, "api/openapi.json");
if (ipsd) {
    const { file, tmp } = await served(ipsd);
    ok = lint(file, "the document ipsd serves") && ok;
    fs.rmSync(tmp, { recursive: true, force: true });
}
process.exit(ok ? 0 : 1);
