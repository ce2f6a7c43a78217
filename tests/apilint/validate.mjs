// validate.mjs: checks that ipsd's answers have the shapes api/openapi.json promises.
//
//   node validate.mjs OPENAPI.json --examples
//       every example in the document (request bodies, answers) validates against its schema;
//   node validate.mjs OPENAPI.json RECORD_DIR... [--min-operations N]
//       every answer the HTTP tests recorded (tests/ipsd_http.py, IPSD_API_RECORD_DIR: one JSON
//       line per answer) is matched to its operation by method and path template, its status must
//       be one the operation documents, and a JSON body (or an event stream's data lines) must
//       validate against that status's schema. Answers to paths outside /api or to no documented
//       operation are counted, not checked (the router's 404/405 for unknown paths).
//
// The document is OpenAPI 3.1, whose schemas are JSON Schema 2020-12: ajv's 2020 dialect with
// ajv-formats. Exit 0 when all is well, 1 with one line per problem, 77 (skip) when the
// dependencies are not installed (`npm ci --prefix tests/apilint`).
import fs from "node:fs";
import path from "node:path";

let Ajv2020, addFormats;
try {
    Ajv2020 = (await import("ajv/dist/2020.js")).default;
    addFormats = (await import("ajv-formats")).default;
} catch {
    console.log("skip: ajv not installed (npm ci --prefix tests/apilint)");
    process.exit(77);
}

const args = process.argv.slice(2);
if (args.length < 2) {
    console.error("usage: node validate.mjs OPENAPI.json (--examples | RECORD_DIR... [--min-operations N])");
    process.exit(2);
}
const docPath = args[0];
const doc = JSON.parse(fs.readFileSync(docPath, "utf8"));
const DOC_ID = "https://ipsd.invalid/openapi.json";

const ajv = new Ajv2020({ strict: false, allErrors: true });
addFormats(ajv);
ajv.addSchema({ ...doc, $id: DOC_ID }, DOC_ID);

const escape = (s) => s.replace(/~/g, "~0").replace(/\//g, "~1");
const compiled = new Map();
function validatorAt(pointer) {
    if (!compiled.has(pointer)) compiled.set(pointer, ajv.compile({ $ref: DOC_ID + "#" + pointer }));
    return compiled.get(pointer);
}
const problems = [];
const describe = (errs) =>
    (errs || []).slice(0, 3).map((e) => `${e.instancePath || "/"} ${e.message}`).join("; ");

// ---- every example validates against the schema beside it ----
function checkExamples() {
    let n = 0;
    for (const [p, item] of Object.entries(doc.paths)) {
        for (const [method, op] of Object.entries(item)) {
            if (typeof op !== "object" || !op.responses) continue;
            const base = `/paths/${escape(p)}/${method}`;
            const media = [];
            if (op.requestBody?.content)
                for (const [ct, m] of Object.entries(op.requestBody.content))
                    media.push([`${base}/requestBody/content/${escape(ct)}`, m, `${method.toUpperCase()} ${p} request`]);
            for (const [st, r] of Object.entries(op.responses))
                for (const [ct, m] of Object.entries(r.content || {}))
                    media.push([`${base}/responses/${st}/content/${escape(ct)}`, m, `${method.toUpperCase()} ${p} ${st}`]);
            for (const [ptr, m, what] of media) {
                if (!m.schema) continue;
                const ex = [];
                if ("example" in m) ex.push(["example", m.example]);
                for (const [k, e] of Object.entries(m.examples || {})) if ("value" in e) ex.push([k, e.value]);
                for (const [k, v] of ex) {
                    n++;
                    const validate = validatorAt(ptr + "/schema");
                    if (!validate(v)) problems.push(`example ${k} of ${what}: ${describe(validate.errors)}`);
                }
            }
        }
    }
    return n;
}

// ---- recorded answers ----
const templates = Object.keys(doc.paths).map((t) => {
    const segs = t.split("/");
    const re = new RegExp("^" + segs.map((s) => (/^\{.*\}$/.test(s) ? "-?[0-9]+" : s.replace(/[.*+?^$()|[\]\\]/g, "\\$&"))).join("/") + "$");
    const literal = segs.filter((s) => !/^\{.*\}$/.test(s)).length;
    return { t, re, literal };
});
function matchTemplate(p) {
    const hits = templates.filter((x) => x.re.test(p)).sort((a, b) => b.literal - a.literal);
    return hits.length ? hits[0].t : null;
}

function checkRecords(dirs, minOps) {
    const covered = new Set();
    let checked = 0, skipped = 0, files = 0;
    for (const dir of dirs) {
        if (!fs.existsSync(dir)) continue;
        for (const f of fs.readdirSync(dir).filter((f) => f.endsWith(".jsonl"))) {
            files++;
            const lines = fs.readFileSync(path.join(dir, f), "utf8").split("\n").filter(Boolean);
            for (const line of lines) {
                const rec = JSON.parse(line);
                let p;
                try {
                    p = decodeURI(rec.path.split("?")[0]);
                } catch {
                    p = rec.path.split("?")[0];
                }
                const t = p.startsWith("/api/") ? matchTemplate(p) : null;
                const op = t && doc.paths[t][rec.method.toLowerCase()];
                if (!op) {
                    skipped++;
                    continue;
                }
                const where = `${f}: ${rec.method} ${rec.path.slice(0, 120)} -> ${rec.status}`;
                const st = String(rec.status);
                const resp = op.responses[st] || op.responses[st[0] + "XX"] || op.responses.default;
                checked++;
                covered.add(`${rec.method} ${t} ${st}`);
                if (!resp) {
                    problems.push(`${where}: status ${st} is not documented for ${rec.method} ${t}`);
                    continue;
                }
                const content = resp.content || {};
                const key = op.responses[st] ? st : op.responses[st[0] + "XX"] ? st[0] + "XX" : "default";
                const base = `/paths/${escape(t)}/${rec.method.toLowerCase()}/responses/${key}/content`;
                if (rec.events !== undefined) {
                    const m = content["text/event-stream"];
                    const evPtr = m && m.schema && m.schema["contentSchema"] ? `${base}/${escape("text/event-stream")}/schema/contentSchema` : null;
                    if (!evPtr) {
                        problems.push(`${where}: an event stream, but the document names no event schema`);
                        continue;
                    }
                    const validate = validatorAt(evPtr);
                    for (const ev of rec.events) {
                        if (!validate(JSON.parse(ev))) problems.push(`${where}: event ${ev.slice(0, 80)}: ${describe(validate.errors)}`);
                    }
                    continue;
                }
                if (Object.keys(content).length === 0) continue; // documented without a body
                if (rec.method === "HEAD" || rec.status === 304) continue;
                if (!content[rec.content_type]) {
                    problems.push(`${where}: content type ${JSON.stringify(rec.content_type)} is not documented (${Object.keys(content).join(", ")})`);
                    continue;
                }
                if (rec.content_type !== "application/json" || !content[rec.content_type].schema) continue;
                let body;
                try {
                    body = JSON.parse(rec.body);
                } catch {
                    problems.push(`${where}: body is not JSON: ${String(rec.body).slice(0, 80)}`);
                    continue;
                }
                const validate = validatorAt(`${base}/${escape(rec.content_type)}/schema`);
                if (!validate(body)) problems.push(`${where}: ${describe(validate.errors)}`);
            }
        }
    }
    const ops = new Set([...covered].map((c) => c.split(" ").slice(0, 2).join(" ")));
    console.log(`${files} record files: ${checked} answers checked, ${skipped} to no documented operation; ` +
        `${ops.size} operations and ${covered.size} (operation, status) pairs seen`);
    if (files === 0) problems.push("no record files: run the HTTP tests first (they write IPSD_API_RECORD_DIR)");
    if (ops.size < minOps) problems.push(`only ${ops.size} operations seen, want at least ${minOps}`);
}

let i = 1;
if (args[1] === "--examples") {
    const n = checkExamples();
    console.log(`${n} examples checked`);
    if (n === 0) problems.push("the document has no examples");
} else {
    const dirs = [];
    let minOps = 1;
    for (; i < args.length; i++) {
        if (args[i] === "--min-operations") minOps = Number(args[++i]);
        else dirs.push(args[i]);
    }
    checkRecords(dirs, minOps);
}
for (const p of problems.slice(0, 60)) console.log("FAIL: " + p);
if (problems.length > 60) console.log(`... and ${problems.length - 60} more`);
process.exit(problems.length ? 1 : 0);
