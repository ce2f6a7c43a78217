// dashboard.test.mjs: the dashboard's end-to-end test in a real browser. Starts a real ipsd on a
// free loopback port with a temporary database and --web pointing at web/, drives Debian's
// chromium through playwright-core like a person (clicks and typing): checks that the forms'
// defaults and bounds are the served OpenAPI document's, creates a sensor, makes a bad scan
// request and checks the API's own error message is shown at the form, submits a small scan,
// waits for the progress to reach done on the page, opens the automatic fit through the scan
// page, and checks what the page shows against GET /api/fits/{id} and its interpolated map
// (GET /api/fits/{id}/interp) and the pixel's raster fetched independently (best r, status,
// F-test; the Plotly figures' data read from their graph divs: the map S and the Wiener baseline
// on one colour scale, axes in µm, the pixel outline, the 3-D surface of the interpolated map, the
// measured signal, the fitted model and the residuals at their spot positions on one scale, a
// hover readout, the AIC/BIC figure's recommended r and its reason, the goodness of fit), a bad
// re-fit value (the API's message at its field, nothing queued) and a re-fit that becomes the
// calibration, the calibration search and its CSV link, the pixel view (its Plotly surface, the
// comparison of two maps whose difference the test recomputes from the API's two maps, the CSV
// download's numbers against the API's), cancels a long scan, no sideways scrolling at 390 px,
// and checks that the page logged no console errors. Then, against a second ipsd whose reads are
// closed (--read-token): the page asks for a token when its reads answer 401, says so when a
// wrong one is entered, reads once the read token is entered, and its event stream (opened with a
// ticket of POST /api/events/ticket, since an EventSource sends no header) gets a new scan's
// events; the ticket never shows in ipsd's request log.
//
// Deterministic on a busy machine: every wait is for a condition (on the page, or polled from
// the API) with a generous deadline, never for a time; the scan cancelled from the page is far
// too long to end first (982081 points; the simulated bench stores about 500 a second here, and
// the cancel comes a few seconds after the start).
//
// usage: node dashboard.test.mjs IPSD WEBDIR [SHOTDIR]   exit 0 pass, 1 fail, 77 skip (no
// node_modules here or in WEBDIR (Plotly.js), or no chromium). Screenshots go to SHOTDIR (ctest:
// BUILD/web-screenshots; default /tmp/ipsd-dashboard-screenshots).
import { spawn } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const HERE = path.dirname(fileURLToPath(import.meta.url));
const CHROMIUM = '/usr/bin/chromium';
const [ipsdBin, webDir, shotArg] = process.argv.slice(2);
// screenshots of the main pages at 1280 px and 390 px, for people to look at
const SHOTS = shotArg || path.join(os.tmpdir(), 'ipsd-dashboard-screenshots');
const TOKEN = 'e2e-Token-7f3a'; // ipsd runs with --token: writes need it
const READ_TOKEN = 'e2e-Reader-41c9'; // the second ipsd also runs with --read-token
const WAIT = 30000; // ms: the deadline of a wait for something the page shows soon
const LONG_WAIT = 90000; // ms: the deadline of a wait for a scan or a fit to finish

function skip(why) {
    console.log(`SKIP: ${why}`);
    process.exit(77);
}

if (!ipsdBin || !webDir) {
    console.error('usage: node dashboard.test.mjs IPSD WEBDIR');
    process.exit(2);
}
if (!fs.existsSync(path.join(HERE, 'node_modules', 'playwright-core'))) {
    skip('tests/web/node_modules is missing: run `npm ci --prefix tests/web` (needs the npm ' +
        'registry) to enable the browser test');
}
if (!fs.existsSync(path.join(webDir, 'node_modules', 'plotly.js-dist-min', 'plotly.min.js'))) {
    skip(`${webDir}/node_modules/plotly.js-dist-min is missing: run \`npm ci --prefix web\` ` +
        '(needs the npm registry) to install the dashboard\'s plotting library');
}
if (!fs.existsSync(CHROMIUM)) skip(`${CHROMIUM} is missing: apt-get install chromium`);
const { chromium } = await import('playwright-core');

// With IPSD_API_RECORD_DIR set (tests/web.cmake sets it), every JSON answer of /api/ the page
// or the test itself gets is appended to DIR/web_dashboard.<pid>.jsonl, the format of
// tests/ipsd_http.py (method, path, status, content type, body, request), which the
// openapi_answers test checks against api/openapi.json; the event stream is not (never ends).
const RECORD_DIR = process.env.IPSD_API_RECORD_DIR;
const RECORD_FILE = RECORD_DIR && path.join(RECORD_DIR, `web_dashboard.${process.pid}.jsonl`);
if (RECORD_DIR) { // this test's answers of an earlier run are stale
    fs.mkdirSync(RECORD_DIR, { recursive: true });
    for (const f of fs.readdirSync(RECORD_DIR)) {
        if (f.startsWith('web_dashboard.') && f.endsWith('.jsonl')) {
            fs.rmSync(path.join(RECORD_DIR, f));
        }
    }
}
let recorded = 0;
function record(method, p, status, contentType, body, request) {
    if (!RECORD_FILE) return;
    const type = (contentType || '').split(';')[0].trim();
    if (!p.startsWith('/api/') || p.startsWith('/api/events') || type !== 'application/json') {
        return;
    }
    const rec = { method, path: p, status, content_type: type, body };
    if (request) rec.request = request;
    fs.appendFileSync(RECORD_FILE, `${JSON.stringify(rec)}\n`);
    recorded++;
}
const pendingRecords = new Set(); // the page's answers whose bodies are still being read

let passed = 0, failed = 0;
function check(cond, what, detail = '') {
    if (cond) {
        passed++;
        console.log(`ok - ${what}`);
    } else {
        failed++;
        console.log(`not ok - ${what}${detail ? `: ${detail}` : ''}`);
    }
    return cond;
}
// The API's error message in words, as the dashboard shows it at a field: its JSON name replaced
// by the input's label, or the label put first (the rule docs/web.md states).
const inWordsTest = (e, label) => (e.message.includes(e.field)
    ? e.message.split(e.field).join(label) : `${label}: ${e.message}`);
const near = (a, b, rel) => Math.abs(a - b) <= rel * Math.max(Math.abs(a), Math.abs(b), 1e-300);

// Polls fn() until it returns a truthy value (returned), up to ms; throws naming what.
async function until(fn, what, ms = WAIT) {
    const end = Date.now() + ms;
    for (;;) {
        const v = await fn();
        if (v) return v;
        if (Date.now() > end) throw new Error(`gave up waiting ${ms / 1000} s for ${what}`);
        await new Promise((r) => setTimeout(r, 100));
    }
}

// ---- the daemon ----

async function startIpsd(tmp, more = []) {
    const portFile = path.join(tmp, 'port');
    const log = fs.openSync(path.join(tmp, 'ipsd.log'), 'w');
    fs.writeFileSync(path.join(tmp, 'token'), `${TOKEN}\n`);
    const proc = spawn(ipsdBin, ['--listen', '127.0.0.1:0', '--port-file', portFile, '--db',
        path.join(tmp, 'ipsd.db'), '--web', webDir, '--token', path.join(tmp, 'token'), ...more],
    { stdio: ['ignore', log, log] });
    let exited = null;
    proc.on('exit', (code, sig) => { exited = { code, sig }; });
    for (let i = 0; i < 200; i++) { // up to 20 s (sanitizer builds start slowly)
        if (exited) break;
        const text = fs.existsSync(portFile) ? fs.readFileSync(portFile, 'utf8').trim() : '';
        if (/^\d+$/.test(text)) return { proc, port: Number(text), exited: () => exited };
        await new Promise((r) => setTimeout(r, 100));
    }
    proc.kill('SIGKILL');
    throw new Error(`ipsd did not start: ${fs.readFileSync(path.join(tmp, 'ipsd.log'), 'utf8')}`);
}

// SIGTERM, and a check that ipsd stopped by itself with status 0 (a sanitizer build's reports
// make it fail).
async function stopIpsd(d, log) {
    if (!d) return;
    if (!d.exited()) d.proc.kill('SIGTERM');
    const end = Date.now() + LONG_WAIT;
    while (!d.exited() && Date.now() < end) await new Promise((r) => setTimeout(r, 100));
    const how = d.exited();
    if (!how) d.proc.kill('SIGKILL');
    const ok = check(how && how.code === 0, 'ipsd exits 0 at SIGTERM', JSON.stringify(how));
    if (!ok && fs.existsSync(log)) {
        console.log(`# ipsd log:\n${fs.readFileSync(log, 'utf8').slice(-3000)}`);
    }
}

// ---- the steps ----

async function typeInto(locator, text) {
    await locator.click();
    await locator.fill('');
    await locator.pressSequentially(String(text));
}

// The schema of request body field FIELD ('raster.area_px') of METHOD PATH in the OpenAPI
// document: $ref followed, allOf merged; undefined when the document has none.
function docRule(doc, method, path, field) {
    const resolve = (s) => {
        if (s?.$ref) return resolve(doc.components.schemas[s.$ref.split('/').pop()]);
        if (s?.allOf) {
            return { properties: Object.assign({}, ...s.allOf.map((p) => resolve(p).properties)) };
        }
        return s;
    };
    let s = resolve(doc.paths[path]?.[method]?.requestBody?.content['application/json'].schema);
    for (const k of field.split('.')) s = resolve(s?.properties?.[k]);
    return s;
}

// Checks the inputs of a form against the document: fields [[name, how]] with how 'value' (the
// default filled in), 'placeholder' (the default shown as the placeholder) or 'none' (bounds
// only): min / max are minimum / maximum, data-exclusive-min is exclusiveMinimum, absent when
// the document has none; every field listed must be in the document and in the form.
async function checkFormRules(form, doc, method, path, fields, what) {
    const attr = (v) => (v === undefined || v === null ? null : String(v));
    for (const [name, how] of fields) {
        const rule = docRule(doc, method, path, name);
        const input = form.locator(`input[data-field="${name}"]`);
        if (!check(rule && await input.count() === 1, `${what}: ${name} is in the document and ` +
            'the form')) continue;
        const got = await input.evaluate((el) => ({ value: el.getAttribute('value'),
            current: el.value, placeholder: el.getAttribute('placeholder'),
            min: el.getAttribute('min'), max: el.getAttribute('max'),
            xmin: el.getAttribute('data-exclusive-min') }));
        const want = { min: attr(rule.minimum), max: attr(rule.maximum),
            xmin: attr(rule.exclusiveMinimum) };
        let ok = got.min === want.min && got.max === want.max && got.xmin === want.xmin;
        if (how === 'value') {
            ok &&= rule.default !== undefined && Number(got.value) === rule.default &&
                Number(got.current) === rule.default;
        } else if (how === 'placeholder') {
            ok &&= rule.default !== undefined && Number(got.placeholder) === rule.default &&
                got.current === '';
        }
        check(ok, `${what}: ${name} has the document's ${how === 'none' ? '' : 'default and '}` +
            'bounds', `form ${JSON.stringify(got)}, document ${JSON.stringify(rule)}`);
    }
}

// Plotly's data and layout of graph [data-testid=testid] once it is drawn (and matches the
// extra attribute selector more, e.g. '[data-colour="log"]').
async function plotly(page, testid, more = '') {
    const sel = `[data-testid="${testid}"][data-state="ready"]${more}`;
    await page.locator(sel).waitFor({ timeout: WAIT });
    return page.$eval(sel, (g) => JSON.parse(JSON.stringify({ data: g.data, layout: g.layout,
        dataset: { ...g.dataset } })));
}
const axisTitle = (ax) => ax?.title?.text ?? ax?.title ?? '';
const sameNumbers = (a, b) => Array.isArray(a) && Array.isArray(b) && a.length === b.length &&
    a.every((v, k) => near(v, b[k], 1e-12));

// The Fit view opened on fit (the API's document) leads with the map it stores as its pixel's
// calibration (web/fit_stored.js): the view's first section, above the Comparison, of kind (the
// API's word: a calibration's `map`, or what the fit's request asked for); its sentence names
// that kind with the API's own numbers (the kriged map's grid, points and divisor grids, whether
// its smooth part was kept; the recommended r and its reason; the shrunk map's r and toward_r;
// and the result's reason why no kriged map could be made, when it gives one), and its heat map
// and S_err are the API's map of that kind (and the calibration's, cal, when given).
async function checkStoredMap(page, fit, kind, what, cal = null) {
    const res = fit.result;
    const sec = page.locator(`[data-testid="stored-section"][data-map="${kind}"]`);
    await sec.waitFor({ timeout: WAIT });
    const order = await page.$$eval('#view section.panel', (ss) => ss.map((x) =>
        x.dataset.testid ?? ''));
    check(order[0] === 'stored-section' && order.indexOf('comparison') > 0,
        `${what}: the stored map's section comes first, the Comparison below it`,
        JSON.stringify(order));
    const sentence = (await sec.locator('[data-testid="stored-sentence"]').textContent()).trim();
    const rec = res.recommended_r;
    let want, map;
    if (kind === 'kriged') {
        const kr = res.kriged_map;
        map = { r: kr.grid, S: kr.S, S_err: kr.S_err };
        want = [`Kriged map on a ${kr.grid} × ${kr.grid} grid from ${res.N} points`,
            ...kr.levels.map((l) => `${l.q} × ${l.q}`),
            kr.smooth ? 'a smooth part (amplitude' : 'without a smooth part'];
    } else if (kind === 'shrunk') {
        const sh = res.shrunk_map;
        map = { r: sh.r, S: sh.S, S_err: sh.S_err };
        want = [`Shrunk map: the paper's r = ${sh.r} map`, `over r = ${sh.toward_r} shrunk`];
    } else {
        const f = res.fits.find((x) => x.r === rec);
        map = { r: rec, S: f.S, S_err: f.S_err };
        want = [`The paper's r = ${rec} map (least squares from ${res.N} points), the ` +
            'recommended r', res.recommended_reason];
    }
    if (kind !== 'kriged' && typeof res.kriged_map?.error === 'string') {
        want.push(`No kriged map could be made: ${res.kriged_map.error}`);
    }
    check(want.every((w) => sentence.includes(w)), `${what}: the stored map's sentence names ` +
        `the ${kind} map with the API's numbers`, `"${sentence}" vs ${JSON.stringify(want)}`);
    check(await sec.locator('h3').textContent() === `The calibration: the ${kind} map`,
        `${what}: the section's heading names the ${kind} map`);
    const g = await plotly(page, 'plot-stored');
    check(g.data[0].z.length === map.r && sameNumbers(g.data[0].z.flat(), map.S) &&
        axisTitle(g.layout.xaxis).includes('µm'), `${what}: the stored map's heat map is the ` +
        `API's ${kind} map on its ${map.r} × ${map.r} grid (µm axes)`,
    JSON.stringify(g.data[0].z).slice(0, 160));
    if (cal) {
        check(cal.map === kind && cal.r === map.r && sameNumbers(cal.S, map.S) &&
            sameNumbers(cal.S_err, map.S_err), `${what}: it is the calibration's map ` +
            `(#${cal.id}, ${cal.map}, r = ${cal.r})`);
    }
    const e = await plotly(page, 'plot-stored-Serr');
    check(sameNumbers(e.data[0].z.flat(), map.S_err), `${what}: the stored map's S_err ` +
        'plotted is the API\'s');
    const top = (t) => page.$eval(`[data-testid="${t}"]`, (x) => x.getBoundingClientRect().top +
        window.scrollY);
    const [yStored, yCmp] = [await top('plot-stored'), await top('plot-maps')];
    check(yStored < yCmp, `${what}: the stored map is drawn above the ` +
        'comparison\'s maps', JSON.stringify([yStored, yCmp]));
}

// The text of the file a click on locator downloads.
async function download(page, locator) {
    const [dl] = await Promise.all([page.waitForEvent('download', { timeout: WAIT }),
        locator.click()]);
    return fs.readFileSync(await dl.path(), 'utf8');
}

// The Scan view's Plotly figures (web/scan_plots.js, scan_frames.js, scan_overview.js) against
// the API's numbers, fetched here: the raster of two pixels of the sub-frame (every point at
// its cell, µm axes, the pixel outline), the log colour and the zoom to the pixel, the CSV and
// JSON downloads, the geometry's spot count, a point's raw frames opened by a click on the
// raster and from the keyboard, and the sub-frame overview.
async function checkScanPage(page, api, scan, sensor) {
    const pitch = sensor.pitch_um, n = scan.raster.points_per_axis;
    const same = (a, b) => a.length === b.length && a.every((v, k) => near(v, b[k], 1e-12));
    // the value in the heat map's cell at each of the API's points, and how many cells are set
    const cells = (tr, px) => {
        const at = (axis, v) => axis.findIndex((a) => Math.abs(a - v) < 1e-9);
        const got = px.x_um.map((x, k) => {
            const i = at(tr.x, x), j = at(tr.y, px.y_um[k]);
            return i < 0 || j < 0 ? NaN : tr.z[j][i];
        });
        return { got, set: tr.z.flat().filter((v) => v !== null).length };
    };
    for (const [dcol, drow] of [[0, 0], [1, -1]]) {
        if (dcol || drow) {
            await page.locator('[data-testid="raster-dcol"]').selectOption(String(dcol));
            await page.locator('[data-testid="raster-drow"]').selectOption(String(drow));
        }
        const px = (await api('GET', `/api/scans/${scan.id}/pixels/${dcol}/${drow}?all=1`)).body;
        const g = await plotly(page, 'raster-map', `[data-pixel="${dcol},${drow}"]`);
        const tr = g.data[0], c = cells(tr, px);
        check(tr.type === 'heatmap' && px.x_um.length === scan.raster.points_total &&
            same(c.got, px.signal_dn) && c.set === px.x_um.length,
        `the raster heat map of pixel (${dcol}, ${drow}) holds the API's ${px.x_um.length} ` +
            'values at their spot positions', `${c.set} cells set`);
        check(axisTitle(g.layout.xaxis).includes('µm') &&
            axisTitle(g.layout.yaxis).includes('µm') && g.layout.shapes.some((sh) =>
            sh.type === 'rect' && sh.x0 === 0 && sh.y0 === 0 && near(sh.x1, pitch, 1e-12) &&
                near(sh.y1, pitch, 1e-12)),
        `the raster of pixel (${dcol}, ${drow}) has µm axes and the pixel outlined`);
        // the CSV download: the API's numbers, sigma by the paper's eq. 5 (computed here: the
        // page takes the API's sigma_dn), the pitch in a comment
        const csv = (await download(page, page.locator('[data-testid="raster-csv"]')))
            .trim().split('\n');
        const comments = csv.filter((l) => l.startsWith('#'));
        const table = csv.filter((l) => !l.startsWith('#'));
        const body = table.slice(1).map((l) => l.split(',').map(Number));
        const rg = px.read_noise_e / px.gain_e_per_dn;
        const sigma = px.signal_dn.map((v) => Math.sqrt((Math.max(v - px.bias_dn, 0) + rg * rg) /
            px.frames));
        check(table[0] === 'x_um,y_um,value,sigma' &&
            comments.some((l) => l.includes(`pitch_um = ${pitch}`)) &&
            body.length === px.x_um.length && same(body.map((r) => r[0]), px.x_um) &&
            same(body.map((r) => r[1]), px.y_um) && same(body.map((r) => r[2]), px.signal_dn) &&
            same(body.map((r) => r[3]), sigma),
        `the raster CSV of pixel (${dcol}, ${drow}) has the API's numbers and the pitch`,
        `${table[0]}; ${body.length} rows; ${comments.join(' | ')}`);
    }
    const json = JSON.parse(await download(page, page.locator('[data-testid="raster-json"]')));
    const px = (await api('GET', `/api/scans/${scan.id}/pixels/1/-1?all=1`)).body;
    check(json.pixel.col === px.pixel.col && json.pixel.row === px.pixel.row &&
        same(json.x_um, px.x_um) && same(json.signal_dn, px.signal_dn) &&
        json.pitch_um === px.pitch_um, 'the raster JSON download is the API\'s');

    // log colour: the cells are log10 of the values, which the hover keeps; then the zoom
    await page.locator('[data-testid="colour-log"]').check();
    const lg = await plotly(page, 'raster-map', '[data-colour="log"]');
    const lc = cells(lg.data[0], px), raw = cells({ ...lg.data[0], z: lg.data[0].customdata }, px);
    check(same(lc.got, px.signal_dn.map(Math.log10)) && same(raw.got, px.signal_dn),
        'log colour: the cells are log10 of the API\'s values, the hover gives the values');
    await page.locator('[data-testid="colour-linear"]').check();
    await page.locator('[data-testid="zoom-pixel"]').check();
    const zg = await plotly(page, 'raster-map', '[data-zoom="pixel"][data-colour="linear"]');
    const xr = zg.layout.xaxis.range, yr = zg.layout.yaxis.range;
    check(xr[0] < 0 && xr[1] > pitch && xr[1] - xr[0] < 1.2 * pitch &&
        Math.max(...yr) > pitch && Math.min(...yr) < 0,
    'zoom to the pixel: the axes span the pixel and a small margin', JSON.stringify([xr, yr]));
    await page.locator('[data-testid="zoom-all"]').check();
    await page.locator('[data-testid="raster-dcol"]').selectOption('0');
    await page.locator('[data-testid="raster-drow"]').selectOption('0');

    // the geometry: one marker per raster point, the POI filled
    const geo = await plotly(page, 'scan-geometry');
    const spots = geo.data.reduce((a, t) => a + t.x.length, 0);
    check(spots === scan.raster.points_total && geo.dataset.points === String(n * n) &&
        geo.layout.shapes.some((sh) => sh.type === 'rect' && sh.x0 === 0 && sh.y0 === 0 &&
            sh.fillcolor && near(sh.x1, pitch, 1e-12)),
    `the geometry figure shows the ${scan.raster.points_total} spot positions and the POI`,
    `${spots} markers`);

    // a point's raw frames: a click on a cell of the raster, then from the keyboard
    const rm = await plotly(page, 'raster-map', '[data-pixel="0,0"][data-zoom="all"]');
    const [i, j] = [3, 5], want = j * n + i;
    const spot = await page.$eval('[data-testid="raster-map"]', (g, [x, y]) => {
        const fl = g._fullLayout, b = g.getBoundingClientRect();
        return [b.left + fl.xaxis._offset + fl.xaxis.l2p(x),
            b.top + fl.yaxis._offset + fl.yaxis.l2p(y)];
    }, [rm.data[0].x[i], rm.data[0].y[j]]);
    await page.mouse.click(spot[0], spot[1]);
    await page.locator(`[data-testid="point-frames"][data-point="${want}"][data-state="ready"]`)
        .waitFor({ timeout: WAIT });
    const pt = (await api('GET', `/api/scans/${scan.id}/points/${want}`)).body;
    let fr = await plotly(page, 'frames-plot');
    check(same(fr.data[0].z.flat(), pt.mean) && same(fr.data[1].z.flat(), pt.raw[0]),
        `a click on a raster cell shows point ${want}'s mean and raw frame from the API`);
    const idx = page.locator('[data-testid="point-index"]');
    await idx.focus();
    await idx.fill(String(want + 1));
    await page.keyboard.press('Enter');
    await page.locator(`[data-testid="point-frames"][data-point="${want + 1}"]` +
        '[data-state="ready"]').waitFor({ timeout: WAIT });
    const frameNo = page.locator('[data-testid="frame-number"]');
    await frameNo.fill(String(pt.frames));
    const pt2 = (await api('GET', `/api/scans/${scan.id}/points/${want + 1}`)).body;
    fr = await until(async () => {
        const f = await plotly(page, 'frames-plot');
        return same(f.data[1].z.flat(), pt2.raw[pt2.frames - 1]) && f;
    }, 'the last raw frame of the next point');
    check(same(fr.data[0].z.flat(), pt2.mean), 'the point and frame typed in are shown');

    // the sub-frame overview: the auto fit's calibration in its pixel, the others placeholders
    const cal = (await api('GET', `/api/sensors/${sensor.id}/pixels/${scan.poi.col}/` +
        `${scan.poi.row}/calibration`)).body;
    const m = scan.raster.sub_px;
    const ov = await plotly(page, 'subframe-overview', '[data-maps="1"]');
    check(ov.data.length === 1 && same(ov.data[0].z.flat(), cal.S) &&
        ov.dataset.missing === String(m * m - 1) &&
        near(ov.data[0].x0, pitch / (2 * cal.r), 1e-12) &&
        near(ov.data[0].y0, pitch / (2 * cal.r), 1e-12) && near(ov.data[0].dx, pitch / cal.r, 1e-12),
    'the sub-frame overview shows the POI\'s calibration in its place, the other pixels empty',
    JSON.stringify(ov.dataset));
    await page.screenshot({ path: path.join(SHOTS, 'scan-1280.png'), fullPage: true });
}

async function run(base, page, api) {
    // the first load parses Plotly's 4.8 MB bundle: slow on a loaded machine
    await page.goto(`${base}/#/scans`, { timeout: LONG_WAIT });
    await page.locator('#live[data-state="live"]').waitFor({ timeout: WAIT });
    check(true, 'dashboard loads and its event stream connects');

    // the forms' defaults and bounds are the served document's (before anything is typed)
    const doc = (await api('GET', '/api/openapi.json')).body;
    const form = page.locator('[data-testid="scan-form"]');
    await form.waitFor({ timeout: WAIT });
    await checkFormRules(form, doc, 'post', '/api/scans', [['poi.col', 'none'],
        ['poi.row', 'none'], ['optics.wavelength_nm', 'value'], ['optics.na', 'value'],
        ['optics.spot_radius_um', 'none'], ['raster.area_px', 'value'],
        ['raster.step_um', 'value'], ['raster.sub_px', 'value'], ['raster.frames', 'value'],
        ['exposure_us', 'placeholder'], ['seed', 'placeholder']], 'scan form');
    const scene = docRule(doc, 'post', '/api/scans', 'scene');
    const sceneSel = form.getByLabel('Scene');
    check(JSON.stringify(await sceneSel.evaluate((s) => [...s.options].map((o) => o.value))) ===
        JSON.stringify(scene.enum) && await sceneSel.inputValue() === scene.default,
    'scan form: the scenes are the document\'s, its default chosen');
    const sf = page.locator('[data-testid="sensor-form"]');
    await checkFormRules(sf, doc, 'post', '/api/sensors', [['n_cols', 'value'],
        ['n_rows', 'value'], ['pitch_um', 'value'], ['gain_e_per_dn', 'placeholder'],
        ['read_noise_e', 'placeholder'], ['bias_dn', 'placeholder'],
        ['full_scale_dn', 'placeholder']], 'sensor form');

    // a sensor, through the "New sensor" form
    await page.getByText('New sensor…').click();
    await typeInto(sf.getByLabel('Model'), 'E2E-CAM');
    await typeInto(sf.getByLabel('Serial'), 'WEB-0001');
    await typeInto(sf.getByLabel('Columns'), 64);
    await typeInto(sf.getByLabel('Rows'), 48);
    // without the token the server refuses the write, and the form says why
    await sf.getByRole('button', { name: 'Create sensor' }).click();
    await sf.locator('.form-error').waitFor({ state: 'visible', timeout: WAIT });
    const denied = await api('POST', '/api/sensors', { model: 'x', serial: 'y' }, false, '');
    const deniedText = await sf.locator('.form-error').textContent();
    check(denied.status === 401 && deniedText.includes(denied.body.error.message),
        'a write without the token shows the API\'s 401 message at the form',
        `page: "${deniedText}", API: ${JSON.stringify(denied.body)}`);
    await typeInto(page.getByLabel('Token', { exact: true }), TOKEN);
    await page.locator('#token-form').getByRole('button', { name: 'Save' }).click();
    await sf.getByRole('button', { name: 'Create sensor' }).click();
    const sensors = async () => (await api('GET', '/api/sensors')).body.items;
    await page.waitForFunction(() => document.querySelector('#scan-sensor')?.selectedOptions[0]
        ?.textContent.includes('E2E-CAM WEB-0001'), null, { timeout: WAIT });
    const sensor = (await sensors()).find((s) => s.serial === 'WEB-0001');
    check(sensor && sensor.n_cols === 64 && sensor.n_rows === 48,
        'the sensor typed into the form is stored (64 x 48)', JSON.stringify(sensor));

    // the scan form: the POI starts at the chosen sensor's centre pixel (64 x 48: (32, 24))
    check(await form.getByLabel('Column').inputValue() === '32' &&
        await form.getByLabel('Row', { exact: true }).inputValue() === '24',
    'the POI is preset to the sensor\'s centre', `${await form.getByLabel('Column')
        .inputValue()}, ${await form.getByLabel('Row', { exact: true }).inputValue()}`);
    // a bad request first (even raster area), then a good one
    await typeInto(form.getByLabel('Column'), 10);
    await typeInto(form.getByLabel('Row', { exact: true }), 12);
    await typeInto(form.getByLabel('Area (pixels, odd)'), 4);
    await typeInto(form.getByLabel('Step (µm)'), 0.5);
    await typeInto(form.getByLabel('Sub-frame (pixels, odd)'), 3);
    await typeInto(form.getByLabel('Frames per point'), 2);
    await form.getByLabel('Scene').selectOption('paperlike');
    await form.getByRole('button', { name: 'Start scan' }).click();
    const errBox = form.locator('.form-error');
    await errBox.waitFor({ state: 'visible', timeout: WAIT });
    const bad = await api('POST', '/api/scans', { sensor_id: sensor.id, poi: { col: 10, row: 12 },
        optics: { wavelength_nm: 550, na: 0.25 },
        raster: { area_px: 4, step_um: 0.5, sub_px: 3, frames: 2 }, scene: 'paperlike' });
    const shown = await errBox.textContent();
    // the API's message in words: its JSON field name replaced by the input's label
    const words = bad.body.error.message.split(bad.body.error.field).join('Area (pixels, odd)');
    check(bad.status === 422 && bad.body.error.field === 'raster.area_px' &&
        bad.body.error.message.includes('raster.area_px') && shown.includes(words) &&
        !shown.includes('raster.area_px'),
    'a bad request shows the API\'s error in words at the form',
    `page: "${shown}", API: ${JSON.stringify(bad.body)}`);
    const areaInput = form.locator('input[data-field="raster.area_px"]');
    const atField = form.locator('[data-testid="field-error"]');
    check(await areaInput.getAttribute('aria-invalid') === 'true' &&
        (await atField.textContent()) === words &&
        await areaInput.getAttribute('aria-describedby') === await atField.getAttribute('id') &&
        await atField.evaluate((el, inp) => el.previousElementSibling === inp,
            await areaInput.elementHandle()),
    'the offending input is marked invalid, with the error right under it',
    await atField.textContent());
    check((await api('GET', '/api/scans')).body.total === 0, 'the bad request stored no scan');

    await typeInto(form.getByLabel('Area (pixels, odd)'), 1);
    await form.getByRole('button', { name: 'Start scan' }).click();
    // the scan is stored, then its row shows (the "queued" notice fades after a while: not it)
    const scan = await until(async () => (await api('GET', '/api/scans')).body.items[0],
        'the scan to be queued');
    await page.locator(`tr[data-scan-id="${scan.id}"]`).waitFor({ timeout: WAIT });
    check(await errBox.isHidden() && await atField.count() === 0,
        'the error box and the field\'s error clear on a good request');
    check(scan && scan.poi.col === 10 && scan.poi.row === 12 && scan.raster.area_px === 1 &&
        scan.raster.frames === 2, 'the scan typed into the form is queued', JSON.stringify(scan));
    const total = scan.raster.points_total;

    // progress on the page until done (events, or the page's own re-reads)
    const row = page.locator(`tr[data-scan-id="${scan.id}"]`);
    await row.and(page.locator('[data-state="done"]')).waitFor({ timeout: LONG_WAIT });
    const progText = await row.locator('.prog-text').textContent();
    const progVal = await row.locator('progress').evaluate((p) => p.value);
    check(progText.startsWith(`${total} / ${total}`) && progVal === 1,
        `the scan row reaches done with ${total} / ${total} points`, `${progText}, ${progVal}`);
    const received = Number(await page.locator('#live').getAttribute('data-received'));
    check(received > 0, 'job events arrived over /api/events', `${received}`);
    console.log(`# event stream: ${await page.locator('#live').getAttribute('title')}`);

    // the automatic fit, opened from the scan page
    await row.locator('td.fit a').waitFor({ timeout: LONG_WAIT });
    await row.getByRole('link', { name: `#${scan.id}`, exact: true }).click();
    const fitLink = page.locator('[data-testid="fit-link"]').first();
    await fitLink.waitFor({ timeout: LONG_WAIT });
    const fitForm = page.locator('[data-testid="fit-form"]');
    await fitForm.waitFor({ timeout: WAIT });
    await checkFormRules(fitForm, doc, 'post', '/api/scans/{id}/fits', [['r_min', 'value'],
        ['r_max', 'value'], ['ftest_r', 'value']], 'fit form');
    check(!(await fitForm.locator('[data-testid="fit-promote"]').isChecked()),
        'fit form: "becomes the calibration" is off by default');
    const pixSel = fitForm.locator('[data-testid="fit-pixels"]');
    await pixSel.selectOption('all');
    check(await fitForm.locator('input[data-field="dcol"]').isDisabled() &&
        await fitForm.locator('input[data-field="drow"]').isDisabled(),
    'fit form: "every pixel the raster covers" disables (and does not send) the pixel offsets');
    await pixSel.selectOption('');
    await checkScanPage(page, api, scan, sensor);
    await fitLink.click();
    await page.locator('[data-testid="best-r-bic"]').waitFor({ timeout: WAIT });
    const fitId = Number(page.url().match(/#\/fits\/(\d+)/)[1]);
    const fit = (await api('GET', `/api/fits/${fitId}`)).body;
    const res = fit.result;
    check(fit.scan_id === scan.id, 'the fit opened is a fit of the scan');
    // first on the page: the map the automatic fit stored as the POI's calibration, of the kind
    // the calibration names (ipsd's --calibration-map)
    const autoCal = (await api('GET', `/api/sensors/${sensor.id}/pixels/${scan.poi.col}/` +
        `${scan.poi.row}/calibration`)).body;
    check(autoCal.fit_id === fitId && fit.calibration?.current === true,
        'the automatic fit is the POI\'s calibration', JSON.stringify([autoCal.fit_id, fitId]));
    await checkStoredMap(page, fit, autoCal.map, 'automatic fit', autoCal);
    const text = async (id) => (await page.locator(`[data-testid="${id}"]`).textContent()).trim();
    check(await text('best-r-aic') === String(res.best_r.aic), 'best r (AIC) matches the API',
        `${await text('best-r-aic')} vs ${res.best_r.aic}`);
    check(await text('best-r-bic') === String(res.best_r.bic), 'best r (BIC) matches the API',
        `${await text('best-r-bic')} vs ${res.best_r.bic}`);
    check(await text('recommended-r') === String(res.recommended_r),
        'recommended r matches the API', `${await text('recommended-r')} vs ${res.recommended_r}`);
    const best = res.fits.find((f) => f.r === res.recommended_r);
    check(await text('shown-r') === `r = ${best.r}`, 'the map shown is the recommended one');
    check(await text('map-status') === best.status, 'the fit status matches the API',
        `${await text('map-status')} vs ${best.status}`);
    // the note under the model selection names the map shown, also when another r is chosen
    check((await text('selection-note')).includes(`are r = ${best.r}, the recommended r`),
        'the selection note: the maps shown are the recommended r', await text('selection-note'));
    const other = res.fits.find((f) => f.r !== best.r && f.S);
    await page.locator('[data-testid="r-select"]').selectOption(String(other.r));
    await page.locator('[data-testid="shown-r"]', { hasText: new RegExp(`^r = ${other.r}$`) })
        .waitFor({ timeout: WAIT });
    const note2 = await text('selection-note');
    check(note2.includes(`are r = ${other.r};`) &&
        note2.includes(`the recommended r is ${best.r}`),
        'after choosing another r the note names it and the recommended one', note2);
    await page.locator('[data-testid="r-select"]').selectOption(String(best.r));
    await page.locator('[data-testid="shown-r"]', { hasText: new RegExp(`^r = ${best.r}$`) })
        .waitFor({ timeout: WAIT });
    const F = Number(await text('ftest-F')), p = Number(await text('ftest-p'));
    check(near(F, res.ftest.F, 1e-5), 'the F statistic matches the API', `${F} vs ${res.ftest.F}`);
    check(near(p, res.ftest.p_value, 1e-3), 'the p-value matches the API',
        `${p} vs ${res.ftest.p_value}`);
    const sig = await page.locator('[data-testid="ftest-verdict"]')
        .getAttribute('data-significant');
    check(sig === String(res.ftest.p_value < 0.05), 'the F-test verdict is p < 0.05',
        `${sig}, p = ${res.ftest.p_value}`);

    // the Plotly figures (web/fit_maps.js): what they plot is read from the graph divs (Plotly
    // keeps each graph's data and layout on its div) and checked against the API's numbers
    const r = best.r, S = best.S, pitch = sensor.pitch_um;
    const graph = async (testid) => {
        const sel = `[data-testid="${testid}"]`;
        await page.locator(`${sel}[data-state="ready"]`).waitFor({ timeout: WAIT });
        return page.$eval(sel, (g) => JSON.parse(JSON.stringify({ data: g.data,
            layout: g.layout })));
    };
    const flat = (z) => z.flat();
    const same = (a, b) => a.length === b.length && a.every((v, k) => near(v, b[k], 1e-12));
    const title = (ax) => ax?.title?.text ?? ax?.title ?? '';
    const maps = await graph('plot-maps');
    const [sTr, wTr] = maps.data;
    check(sTr.type === 'heatmap' && sTr.z.length === r && sTr.z.every((row) => row.length === r) &&
        same(flat(sTr.z), S), `the heat map plots the API's ${r} x ${r} map S`,
    JSON.stringify(sTr.z));
    check(same(sTr.x, S.slice(0, r).map((_, i) => (i + 0.5) * pitch / r)) &&
        same(sTr.y, sTr.x), 'the map\'s cells sit at the sub-pixel centres in µm (the sensor\'s ' +
        `pitch ${pitch} µm)`, JSON.stringify(sTr.x));
    check(title(maps.layout.xaxis).includes('µm') && title(maps.layout.yaxis).includes('µm') &&
        title(maps.layout.xaxis2).includes('µm') && title(maps.layout.yaxis2).includes('µm'),
    'the heat maps\' axes are in µm', JSON.stringify([title(maps.layout.xaxis),
        title(maps.layout.yaxis)]));
    check(maps.layout.shapes.some((sh) => sh.type === 'rect' && sh.x0 === 0 && sh.y0 === 0 &&
        near(sh.x1, pitch, 1e-12) && near(sh.y1, pitch, 1e-12)), 'the pixel outline is drawn');
    const W = res.wiener.S;
    const lo = Math.min(...S, ...W), hi = Math.max(...S, ...W);
    check(wTr?.type === 'heatmap' && same(flat(wTr.z), W) && wTr.z.length === res.wiener.ny,
        'the Wiener baseline plotted is the API\'s');
    check(sTr.coloraxis === 'coloraxis' && wTr.coloraxis === 'coloraxis' &&
        near(maps.layout.coloraxis.cmin, lo, 1e-12) && near(maps.layout.coloraxis.cmax, hi, 1e-12),
    'S and the Wiener baseline share one colour scale spanning both', JSON.stringify([
        maps.layout.coloraxis.cmin, maps.layout.coloraxis.cmax, lo, hi]));
    check(/viridis/i.test(JSON.stringify(maps.layout.coloraxis.colorscale)),
        'the maps use viridis');

    // hover: the pointer on the cell of the largest S shows its value
    const kMax = S.indexOf(Math.max(...S));
    await page.locator('[data-testid="plot-maps"]').scrollIntoViewIfNeeded();
    const spot = await page.$eval('[data-testid="plot-maps"]', (g, [x, y]) => {
        const fl = g._fullLayout, b = g.getBoundingClientRect();
        return [b.left + fl.xaxis._offset + fl.xaxis.l2p(x),
            b.top + fl.yaxis._offset + fl.yaxis.l2p(y)];
    }, [sTr.x[kMax % r], sTr.y[Math.floor(kMax / r)]]);
    await page.mouse.move(spot[0], spot[1]);
    const tip = page.locator('[data-testid="plot-maps"] .hoverlayer .hovertext')
        .filter({ hasText: /S = / });
    await tip.first().waitFor({ timeout: WAIT });
    const readout = (await tip.first().textContent()).replace(/\u2212/g, '-');
    const m = readout.match(/S = ([-0-9.e]+)/);
    check(m && near(Number(m[1]), S[kMax], 1e-4), 'hovering a cell shows its S value',
        `"${readout}" vs ${S[kMax]}`);

    // the interpolated map (GET /api/fits/{id}/interp, fetched by the test too) as a surface
    const ip = (await api('GET', `/api/fits/${fitId}/interp?r=${r}&n=100`)).body;
    const n = ip.n;
    const surf = await graph('plot-surface');
    check(ip.r === r && n === 100 && surf.data[0].type === 'surface' &&
        surf.data[0].z.length === n && same(flat(surf.data[0].z), ip.S),
    'the 3-D surface plots the API\'s interpolated map');
    const sc = surf.layout.scene;
    check(title(sc.xaxis).includes('µm') && title(sc.yaxis).includes('µm'),
        'the surface\'s axes are in µm', JSON.stringify([title(sc.xaxis),
            title(sc.yaxis)]));
    const surfTitle = await page.locator('figure:has([data-testid="plot-surface"]) figcaption')
        .textContent();
    check(surfTitle.includes(ip.method), 'the interpolated map names its method', surfTitle);

    // residuals against spot position: the fit's residuals at the positions of the scan's raster
    // of the pixel (its default answer: the points strictly inside, those the fit used)
    const px = (await api('GET', `/api/scans/${scan.id}/pixels/${fit.dcol}/${fit.drow}`)).body;
    const resid = best.residuals;
    const kept = resid.map((_, k) => k).filter((k) => Number.isFinite(resid[k]));
    const rg = await graph('plot-resid');
    const rTr = rg.data.find((d) => d.name === 'residual');
    const mTr = rg.data.find((d) => d.name === 'model');
    const dTr = rg.data.find((d) => d.name === 'signal');
    check(px.x_um.length === resid.length && kept.length > 0 &&
        same(rTr.marker.color, kept.map((k) => resid[k])),
    'the residual plot shows the API\'s residuals', `${rTr.marker.color.length} plotted, ` +
        `${kept.length} finite of ${resid.length}; raster ${px.x_um.length} points`);
    check(same(rTr.x, kept.map((k) => px.x_um[k])) && same(rTr.y, kept.map((k) => px.y_um[k])),
        'each residual sits at its spot position (µm)');
    const modelKept = kept.filter((k) => Number.isFinite(best.model_dn?.[k]));
    check(mTr && modelKept.length === kept.length &&
        same(mTr.marker.color, modelKept.map((k) => best.model_dn[k])) &&
        same(mTr.x, modelKept.map((k) => px.x_um[k])),
    'the model raster plots the API\'s model_dn at the spot positions',
    mTr ? `${mTr.marker.color.length} plotted, ${modelKept.length} expected` : 'no model trace');
    // the model is the signal less the residual times sigma: it must sit within a few sigma of
    // the signal (sigma >= the read noise and < the signal's own size here)
    check(modelKept.every((k) => Math.abs(px.signal_dn[k] - best.model_dn[k]) <
        Math.max(1, Math.abs(resid[k])) * Math.abs(px.signal_dn[k]) + 1e-9),
    'model and signal differ by no more than the residuals allow');
    check(dTr.marker.coloraxis === 'coloraxis' && mTr?.marker.coloraxis === 'coloraxis' &&
        rTr.marker.coloraxis === 'coloraxis2', 'signal and model share one colour scale');
    const rangeOf = (ax) => JSON.stringify(rg.layout[ax].range);
    check(['xaxis', 'xaxis2', 'xaxis3'].every((ax) => title(rg.layout[ax]).includes('µm') &&
        rangeOf(ax) === rangeOf('xaxis')) && rg.layout.shapes.length === 3,
    'signal, model and residuals side by side on one µm scale, the pixel outlined on each',
    ['xaxis', 'xaxis2', 'xaxis3'].map(rangeOf).join(' '));

    // the shrunk map (fit/shrink.h) is one more choice of the selector: its heat map is the
    // API's shrunk_map.S, named in "Map shown"; then back to the recommended map
    const shr = res.shrunk_map;
    check(shr && shr.r === best.r, 'the fit has a shrunk map at the recommended r',
        JSON.stringify(shr && { r: shr.r, toward_r: shr.toward_r }));
    if (shr) {
        await page.locator('[data-testid="r-select"]').selectOption('shrunk');
        await page.locator('[data-testid="shown-r"]', { hasText: `shrunk toward r = ${shr.toward_r}` })
            .waitFor({ timeout: WAIT });
        const sm = await graph('plot-maps');
        check(same(flat(sm.data[0].z), shr.S), 'choosing the shrunk map plots the API\'s shrunk S',
            JSON.stringify(sm.data[0].z).slice(0, 200));
        check((await text('selection-note')).includes('are the shrunk map'),
            'the note says the maps shown are the shrunk map', await text('selection-note'));
        const sRes = await graph('plot-Sres');
        check(same(flat(sRes.data[0].z), shr.S_res), 'the shrunk map\'s resolution error S_res ' +
            'plotted is the API\'s', JSON.stringify(sRes.data[0].z).slice(0, 120));
        await page.locator('[data-testid="r-select"]').selectOption(String(best.r));
        await page.locator('[data-testid="shown-r"]', { hasText: new RegExp(`^r = ${best.r}$`) })
            .waitFor({ timeout: WAIT });
    }

    // model selection: AIC and BIC against r, the recommended r marked, its reason in words
    const sel = await graph('plot-selection');
    const aicTr = sel.data.find((d) => d.name === 'AIC');
    const withAic = res.fits.filter((f) => Number.isFinite(f.aic));
    check(aicTr && same(aicTr.x, withAic.map((f) => f.r)) &&
        same(aicTr.y, withAic.map((f) => f.aic)), 'the AIC curve plots the API\'s AIC against r');
    const recMarks = sel.layout.shapes.filter((sh) => sh.name === 'recommended');
    check(recMarks.length > 0 && recMarks.every((sh) => sh.x0 === res.recommended_r &&
        sh.x1 === res.recommended_r), 'the model-selection figure marks the recommended r = ' +
        `${res.recommended_r}`, JSON.stringify(recMarks.map((sh) => sh.x0)));
    const hasCv = res.fits.some((f) => Number.isFinite(f.cv_chi2));
    check(!hasCv || sel.data.some((d) => d.name === 'cross-validation χ²'),
        'the cross-validation χ² is drawn when the fit has it', String(hasCv));
    const why = await text('selection-reason');
    check(why.includes(`r = ${res.recommended_r}`) && why.includes(res.recommended_reason),
        'the recommended r\'s reason is said in words', why);
    const good = page.locator('[data-testid="goodness"]');
    const poor = best.chi2_p < 1e-3;
    const goodText = await good.textContent();
    check(await good.getAttribute('data-poor') === String(poor) &&
        goodText.includes(poor ? 'poor_fit' : 'consistent with the noise model'),
    `the goodness of fit in words (p = ${best.chi2_p})`, goodText);
    const sErr = await graph('plot-Serr');
    check(same(flat(sErr.data[0].z), best.S_err), 'the S_err map plotted is the API\'s');
    const resBest = await graph('plot-Sres');
    check(shr && same(flat(resBest.data[0].z), shr.S_res), 'the recommended map shows the ' +
        'resolution error of its r (the API\'s shrunk_map.S_res) beside S_err');
    check(await page.locator('[data-testid="sweep-table"] tbody tr').count() === res.fits.length,
        'the model-selection table has a row per r');
    await page.screenshot({ path: path.join(SHOTS, 'fit-1280.png'), fullPage: true });

    // the fit page's re-fit form: a bad value shows the API's message at its field, queues
    // nothing
    const refitForm = page.locator('[data-testid="refit"] [data-testid="fit-form"]');
    await refitForm.waitFor({ timeout: WAIT });
    check(await refitForm.locator('input[data-field="dcol"]').inputValue() === String(fit.dcol),
        'the re-fit form starts from the fit\'s pixel');
    const jobsBefore = (await api('GET', '/api/jobs?limit=1000')).body.total;
    const rMaxRule = docRule(doc, 'post', '/api/scans/{id}/fits', 'r_max');
    const tooBig = rMaxRule.maximum + 1;
    await typeInto(refitForm.getByLabel('r max'), tooBig);
    await refitForm.getByRole('button', { name: 'Queue fit' }).click();
    const refitErr = refitForm.locator('[data-testid="field-error"]');
    await refitErr.waitFor({ timeout: WAIT });
    const badFit = await api('POST', `/api/scans/${scan.id}/fits`, { r_max: tooBig });
    const rMaxInput = refitForm.locator('input[data-field="r_max"]');
    check(badFit.status === 422 && badFit.body.error.field === 'r_max' &&
        (await refitErr.textContent()) === inWordsTest(badFit.body.error, 'r max') &&
        await rMaxInput.getAttribute('aria-invalid') === 'true' &&
        await refitErr.evaluate((el, inp) => el.previousElementSibling === inp,
            await rMaxInput.elementHandle()),
    'a bad re-fit value shows the API\'s message right under its field',
    `page: "${await refitErr.textContent()}", API: ${JSON.stringify(badFit.body)}`);
    check((await api('GET', '/api/jobs?limit=1000')).body.total === jobsBefore,
        'the bad re-fit queued nothing');
    await typeInto(refitForm.getByLabel('r max'), rMaxRule.default);

    // the calibration database: the search lists the auto fit's calibration, with its CSV
    await page.getByRole('navigation').getByRole('link', { name: 'Calibrations' }).click();
    await page.locator('[data-testid="calib-form"]').getByRole('button', { name: 'Search' })
        .click();
    const calRow = page.locator('[data-testid="calib-table"] tbody tr').first();
    await calRow.waitFor({ timeout: WAIT });
    const cals = (await api('GET', `/api/calibrations?sensor=${sensor.id}`)).body.items;
    const calId = Number(await calRow.getAttribute('data-calib-id'));
    check(cals.length === 1 && calId === cals[0].id && cals[0].fit_id === fitId,
        'the calibration search lists the auto fit\'s calibration', JSON.stringify(cals.map((c) =>
            [c.id, c.fit_id])));
    const csvHref = await calRow.getByRole('link', { name: `CSV of calibration #${calId}` })
        .getAttribute('href');
    const csv = await api('GET', csvHref, undefined, true);
    const lines = csv.body.trim().split('\n');
    check(csv.status === 200 && lines[0].startsWith('calibration_id,') &&
        lines.length === 1 + cals[0].r * cals[0].r, 'the CSV link gives one line per sub-pixel',
    `${csv.status}, ${lines.length} lines`);
    await calRow.getByRole('link', { name: 'map' }).click();
    await page.locator('[data-testid="history-table"]').waitFor({ timeout: WAIT });
    check(await page.locator('[data-testid="history-table"] tbody tr').count() === 1,
        'the pixel view shows the history of the pixel');
    const calS = await graph('plot-cal-S');
    check(same(flat(calS.data[0].z), cals[0].S) && title(calS.layout.xaxis).includes('µm'),
        'the pixel view plots the calibration\'s map S on µm axes');

    check((await page.locator('[data-testid="current-why"]').textContent())
        .includes(`automatic fit of scan ${scan.id}`), 'the pixel view says why its map is current');
    const mapPhrase = { recommended: `recommended r's own least-squares map (r = ${cals[0].r})`,
        shrunk: `shrunk map: r = ${cals[0].r}'s detail`,
        kriged: `kriged map on a fine ${cals[0].r} × ${cals[0].r} grid` }[cals[0].map];
    check(mapPhrase && (await page.locator('[data-testid="current-map"]').textContent())
        .includes(mapPhrase) && await page.locator('[data-testid="current-kind"]')
        .getAttribute('data-map') === cals[0].map,
    'the pixel view says which map of its fit the calibration holds (the API\'s map)',
    cals[0].map);
    const mapText = await page.locator('[data-testid="current-map"]').textContent();
    check(Array.isArray(cals[0].S_res) === mapText.includes('resolution error S_res rms'),
        'the pixel view gives the resolution error when the API has one',
        JSON.stringify([cals[0].S_res?.length, mapText]));

    // a re-fit is stored as a fit only; its Fit view says so, and promotes it with a reason typed
    // and sent from the keyboard (POST /api/fits/{id}/promote)
    const refitJob = (await api('POST', `/api/scans/${scan.id}/fits`, { r_max: 2, krige: true }))
        .body.job;
    const refit = (await until(async () => {
        const j = (await api('GET', `/api/jobs/${refitJob.id}`)).body;
        return j.state === 'done' && j;
    }, 'the re-fit to be done', LONG_WAIT)).fit_id;
    await page.goto(`${base}/#/fits/${refit}`);
    const calState = page.locator('[data-testid="calibration-state"]');
    await page.locator('[data-testid="calibration-state"][data-current="false"]')
        .waitFor({ timeout: WAIT });
    check((await calState.textContent()).includes(`calibration #${calId}`),
        'the re-fit\'s view: stored as a fit, the current calibration is the automatic fit\'s',
        await calState.textContent());
    // its stored map is the one its request asked for (the job's params: no "map", so the
    // recommended one), although it has a kriged map too
    const refitDoc = (await api('GET', `/api/fits/${refit}`)).body;
    const refitAsked = (await api('GET', `/api/jobs/${refitJob.id}`)).body.params.map ??
        'recommended';
    await checkStoredMap(page, refitDoc, refitAsked, 'a re-fit stored as a fit');
    check(await page.locator('[data-testid="stored-sentence"]').getAttribute('data-source') ===
        'fit' && refitDoc.calibration.map === refitAsked,
    'a fit that is no calibration: its map kind is the fit record\'s calibration.map');
    // the re-fit asked for the kriged map (fit/krige.h): one more choice of the selector, its
    // heat map the API's kriged_map.S on its grid, named in "Map shown"
    const kr = (await api('GET', `/api/fits/${refit}`)).body.result.kriged_map;
    check(kr && Array.isArray(kr.S) && kr.S.length === kr.grid * kr.grid,
        'the re-fit has a kriged map', JSON.stringify(kr && { grid: kr.grid, error: kr.error }));
    if (kr && Array.isArray(kr.S)) {
        await page.locator('[data-testid="r-select"]').selectOption('kriged');
        await page.locator('[data-testid="shown-r"]', { hasText: `kriged, ${kr.grid} × ${kr.grid}` })
            .waitFor({ timeout: WAIT });
        const km = await graph('plot-maps');
        check(same(flat(km.data[0].z), kr.S) && km.data[0].z.length === kr.grid,
            'choosing the kriged map plots the API\'s kriged S on its grid',
            JSON.stringify(km.data[0].z).slice(0, 200));
        check((await text('selection-note')).includes('are the kriged map'),
            'the note says the maps shown are the kriged map', await text('selection-note'));
    }
    const reason = page.locator('[data-testid="promote-form"]').getByLabel('Reason');
    await reason.focus();
    await page.keyboard.type('checked by the dashboard test');
    await page.keyboard.press('Enter');
    await page.locator('[data-testid="calibration-state"][data-current="true"]')
        .waitFor({ timeout: WAIT });
    check(await calState.evaluate((el) => el === document.activeElement),
        'after promoting, the focus is on the new state');
    const now = (await api('GET', `/api/sensors/${sensor.id}/pixels/${scan.poi.col}/` +
        `${scan.poi.row}/calibration`)).body;
    check(now.fit_id === refit && now.by === 'dashboard' && now.supersedes === calId &&
        now.reason === 'checked by the dashboard test', 'the promoted re-fit is the calibration, ' +
        'with the reason typed', JSON.stringify([now.fit_id, now.by, now.supersedes, now.reason]));

    // where no kriged map can be made (an upload of 2 points to a pixel), the calibration is the
    // recommended map and both views give the server's sentence why (stored_map.why, map_note)
    const pixelFile = (await api('GET', `/api/scans/${scan.id}/pixels/0/0`)).body;
    const few = { ...pixelFile };
    for (const k of ['x_um', 'y_um', 'signal_dn']) few[k] = pixelFile[k].slice(40, 42);
    const fewCol = scan.poi.col + 1;
    const fewJob = (await api('POST', '/api/fits', { scan: few, sensor_id: sensor.id,
        pixel: { col: fewCol, row: scan.poi.row }, map: 'kriged' })).body.job;
    const fewFit = (await until(async () => {
        const j = (await api('GET', `/api/jobs/${fewJob.id}`)).body;
        return j.state === 'done' && j;
    }, 'the 2-point upload to be fitted', LONG_WAIT)).fit_id;
    const fewCal = (await api('GET', `/api/sensors/${sensor.id}/pixels/${fewCol}/` +
        `${scan.poi.row}/calibration`)).body;
    const fewWhy = (await api('GET', `/api/fits/${fewFit}`)).body.result.stored_map?.why;
    check(fewCal.map === 'recommended' && typeof fewCal.map_note === 'string' &&
        fewCal.map_note === fewWhy && fewWhy.includes('at least 3 usable points'),
    'a 2-point upload: the recommended map, with map_note = stored_map.why',
    JSON.stringify([fewCal.map, fewCal.map_note, fewWhy]));
    await page.goto(`${base}/#/fits/${fewFit}`);
    await page.locator('[data-testid="stored-no-kriged"]').waitFor({ timeout: WAIT });
    check(await text('stored-no-kriged') === fewWhy,
        'the Fit view gives the server\'s sentence on why the map is not kriged',
        await text('stored-no-kriged'));
    await page.goto(`${base}/#/sensors/${sensor.id}/pixels/${fewCol}/${scan.poi.row}`);
    await page.locator('[data-testid="current-map-note"]').waitFor({ timeout: WAIT });
    check(await text('current-map-note') === fewCal.map_note,
        'the Pixel view gives the calibration\'s map_note', await text('current-map-note'));

    // a fit with the geometry fitted first (an upload of the pixel's file, fit_geometry): the
    // Fit view's Result gives the API's radius, offset and model
    const geoJob = (await api('POST', '/api/fits', { scan: pixelFile, fit_geometry: true,
        geometry_r: 3, r_max: 3 })).body.job;
    const geoFit = (await until(async () => {
        const j = (await api('GET', `/api/jobs/${geoJob.id}`)).body;
        return j.state === 'done' && j;
    }, 'the upload with fit_geometry to be fitted', LONG_WAIT)).fit_id;
    const geo = (await api('GET', `/api/fits/${geoFit}`)).body.result.geometry;
    await page.goto(`${base}/#/fits/${geoFit}`);
    await page.locator('[data-testid="geometry-R"]').waitFor({ timeout: WAIT });
    const geoModel = page.locator('[data-testid="geometry-model"]');
    check(geo && geo.model === 'kriged' &&
        Number(await page.locator('[data-testid="geometry-R"]').getAttribute('data-value')) ===
            geo.spot_radius_um &&
        (await text('geometry-R')).startsWith(geo.spot_radius_um.toFixed(4)) &&
        (await text('geometry-offset')).includes(`dx ${geo.dx_um.toFixed(4)}`) &&
        await geoModel.getAttribute('data-model') === geo.model &&
        await geoModel.getAttribute('data-status') === geo.status,
    'the Fit view gives the fitted geometry the API gives, and the model that made it',
    JSON.stringify([geo, await text('geometry-R'), await text('geometry-model')]));
    await page.goto(`${base}/#/fits/${refit}`);

    // a re-fit from the Fit view that becomes the calibration ("promote": true)
    const rf2 = page.locator('[data-testid="refit"] [data-testid="fit-form"]');
    await rf2.waitFor({ timeout: WAIT });
    await typeInto(rf2.getByLabel('r min'), 1);
    await typeInto(rf2.getByLabel('r max'), 7);
    await typeInto(rf2.getByLabel('F-test r'), 7);
    // the map it stores: the form offers the API's words, and this re-fit stores the kriged map
    const mapWords = docRule(doc, 'post', '/api/scans/{id}/fits', 'map').enum;
    check(JSON.stringify(await rf2.locator('[data-testid="fit-map"] option').evaluateAll((os) =>
        os.map((o) => o.value))) === JSON.stringify(mapWords) && mapWords.includes('kriged'),
    'the re-fit form offers the maps the API knows', JSON.stringify(mapWords));
    await rf2.locator('[data-testid="fit-map"]').selectOption('kriged');
    await rf2.locator('[data-testid="fit-promote"]').check();
    await rf2.getByRole('button', { name: 'Queue fit' }).click();
    const link = page.locator('[data-testid="refit-link"]');
    await link.waitFor({ timeout: LONG_WAIT });
    const promotedFit = Number((await link.textContent()).replace(/\D/g, ''));
    const pf = (await api('GET', `/api/fits/${promotedFit}`)).body;
    const calNow = (await api('GET', `/api/sensors/${sensor.id}/pixels/${scan.poi.col}/` +
        `${scan.poi.row}/calibration`)).body;
    check(pf.calibration?.current === true && calNow.fit_id === promotedFit &&
        calNow.supersedes === now.id, 'a re-fit with "becomes the calibration" ticked is the ' +
        'pixel\'s calibration', JSON.stringify([promotedFit, pf.calibration, calNow.fit_id,
            pf.params, pf.result?.recommended_r, pf.result?.recommended_reason, pf.state,
            pf.result?.fits?.map((f) => [f.r, f.status])]));
    const pk = pf.result?.kriged_map;
    check(calNow.map === 'kriged' && pk && calNow.r === pk.grid &&
        same(calNow.S, pk.S), 'the form\'s "Map stored: kriged" stored the result\'s kriged map ' +
        'on its grid as the calibration', JSON.stringify([calNow.map, calNow.r,
        pk?.grid, pk?.error]));

    // its Fit view leads with the kriged map it stored, the calibration's
    await page.goto(`${base}/#/fits/${promotedFit}`);
    await checkStoredMap(page, pf, calNow.map, 'the re-fit stored as the kriged map', calNow);

    // a fit that can store no map (r = 12 alone: more parameters than the 121 points) asked for
    // the kriged map: its first section says so, with the result's own reason why no kriged map
    // could be made
    const noneJob = (await api('POST', `/api/scans/${scan.id}/fits`, { r_min: 12, r_max: 12,
        map: 'kriged' })).body.job;
    const noneFit = (await until(async () => {
        const j = (await api('GET', `/api/jobs/${noneJob.id}`)).body;
        return j.state === 'done' && j;
    }, 'the r = 12 fit to be done', LONG_WAIT)).fit_id;
    const noneDoc = (await api('GET', `/api/fits/${noneFit}`)).body;
    const whyNot = noneDoc.result.kriged_map?.error;
    check(noneDoc.calibration === null && typeof whyNot === 'string',
        'the r = 12 fit offers no map and its result says why it has no kriged map',
        JSON.stringify([noneDoc.calibration, noneDoc.result.kriged_map]));
    await page.goto(`${base}/#/fits/${noneFit}`);
    const noneSec = page.locator('[data-testid="stored-section"][data-map="none"]');
    await noneSec.waitFor({ timeout: WAIT });
    const noneText = await noneSec.locator('[data-testid="stored-sentence"]').textContent();
    check(noneText.includes('no map to store as a calibration') &&
        noneText.includes(`No kriged map could be made: ${whyNot}`) &&
        await noneSec.locator('[data-testid="plot-stored"]').count() === 0,
    'a fit without a map: its first section says so and why no kriged map could be made, ' +
        'in the API\'s words', noneText);

    // the pixel view: its current map as Plotly figures, two maps compared, the CSV download
    const pixelView = `#/sensors/${sensor.id}/pixels/${scan.poi.col}/${scan.poi.row}`;
    await page.goto(`${base}/${pixelView}`);
    await page.locator('[data-testid="current-map"]').waitFor({ timeout: WAIT });
    check((await page.locator('[data-testid="current-map"]').textContent())
        .includes(`kriged map on a fine ${calNow.r} × ${calNow.r} grid`),
    'the pixel view says the calibration holds the kriged map, on its grid',
    await page.locator('[data-testid="current-map"]').textContent());
    const cmp = await graph('plot-compare');
    const A = calNow, B = now; // the default comparison: the current map and the one before
    const [zA, zB, zD] = cmp.data.map((d) => flat(d.z));
    check(same(zA, A.S) && same(zB, B.S), 'the compare view shows the API\'s two maps, the ' +
        'current one and the one it replaced');
    // the difference recomputed here: same r cell by cell; else both on the lcm grid, each cell
    // the sub-pixel under its centre
    const gcd = (a, b) => (b ? gcd(b, a % b) : a);
    // docs/web.md: the lcm when at most 192, else 4 cells per cell of the finer map (<= 192)
    const lcm = A.r * B.r / gcd(A.r, B.r);
    const nC = A.r === B.r ? A.r : lcm <= 192 ? lcm : Math.min(192, 4 * Math.max(A.r, B.r));
    const pick = (m, i, j) => m.S[Math.floor((j + 0.5) / nC * m.r) * m.r +
        Math.floor((i + 0.5) / nC * m.r)];
    const want = [];
    for (let j = 0; j < nC; j++) for (let i = 0; i < nC; i++) want.push(pick(A, i, j) - pick(B, i, j));
    check(zD.length === nC * nC && zD.every((v, k) => Math.abs(v - want[k]) <= 1e-12 *
        Math.max(1, Math.abs(want[k]))), `the difference map is A − B of the API's maps ` +
        `(r = ${A.r} and ${B.r}, on ${nC} × ${nC})`, JSON.stringify(zD.slice(0, 6)));
    const cmpNote = await page.locator('figure:has([data-testid="plot-compare"])').textContent();
    check(A.r === B.r ? cmpNote.includes('sub-pixel by sub-pixel')
        : cmpNote.includes(`resampled onto a common ${nC} × ${nC} grid`),
    'the compare view says whether it resampled', cmpNote);
    check(/viridis/i.test(JSON.stringify(cmp.layout.coloraxis.colorscale)) &&
        cmp.data[0].coloraxis === 'coloraxis' && cmp.data[1].coloraxis === 'coloraxis',
    'A and B share one colour scale');
    const hist = await graph('plot-history');
    const histApi = (await api('GET', `/api/sensors/${sensor.id}/pixels/${scan.poi.col}/` +
        `${scan.poi.row}/history`)).body.items;
    check(hist.data.length === histApi.length && hist.data.every((d, k) =>
        same(flat(d.z), histApi[k].S)), `the history as ${histApi.length} small multiples, the ` +
        'API\'s maps newest first');
    // the pixel view names each map's kind, the API's `map`: the current one's heading, its
    // sentence on how it was made (from its fit), each history row and small multiple
    check(await page.locator('[data-testid="current-kind"]').getAttribute('data-map') ===
        calNow.map && (await page.locator('#cur-h').textContent()).includes(`the ${calNow.map} ` +
        `map, ${calNow.r} × ${calNow.r}`), 'the pixel view\'s heading names the current map\'s ' +
        `kind (${calNow.map})`, await page.locator('#cur-h').textContent());
    const how = page.locator('[data-testid="current-how"]:not([hidden])');
    await how.waitFor({ timeout: WAIT });
    check((await how.textContent()).includes(`Kriged map on a ${calNow.r} × ${calNow.r} grid ` +
        `from ${pf.result.N} points`), 'the pixel view says how the kriged map was made, in the ' +
        'Fit view\'s words', await how.textContent());
    const histKinds = await page.locator('[data-testid="history-map"]').allTextContents();
    check(JSON.stringify(histKinds) === JSON.stringify(histApi.map((c) => c.map)),
        'the history table names each calibration\'s map kind (the API\'s)',
        JSON.stringify(histKinds));
    check(hist.layout.annotations.every((a, k) => a.text.includes(`${histApi[k].map} ` +
        `${histApi[k].r}×${histApi[k].r}`)), 'each small multiple is titled with its map kind');
    const calSurf = await graph('plot-surface');
    const calIp = (await api('GET', `/api/calibrations/${A.id}/interp?n=100`)).body;
    check(same(flat(calSurf.data[0].z), calIp.S), 'the pixel view\'s surface is the ' +
        'calibration\'s interpolated map from the API');
    const [dl] = await Promise.all([page.waitForEvent('download'),
        page.locator('[data-testid="download-csv"]').click()]);
    const csvText = fs.readFileSync(await dl.path(), 'utf8').trim().split('\n');
    const head = csvText[0].split(',');
    const col = (name) => head.indexOf(name);
    const rowsCsv = csvText.slice(1).map((l) => l.split(','));
    const pitchOk = rowsCsv.every((c) => Number(c[col('pitch_um')]) === sensor.pitch_um);
    const valuesOk = rowsCsv.length === A.r * A.r && rowsCsv.every((c) => {
        const i = Number(c[col('i')]), j = Number(c[col('j')]), k = j * A.r + i;
        return Number(c[col('S')]) === A.S[k] && Number(c[col('S_err')]) === A.S_err[k] &&
            (A.S_res ? Number(c[col('S_res')]) === A.S_res[k] : c[col('S_res')] === '') &&
            near(Number(c[col('x_um')]), (i + 0.5) * sensor.pitch_um / A.r, 1e-12) &&
            near(Number(c[col('y_um')]), (j + 0.5) * sensor.pitch_um / A.r, 1e-12);
    });
    check(dl.suggestedFilename().endsWith('.csv') && pitchOk && valuesOk,
        'the CSV download has the API\'s S, S_err and S_res, positions in µm and the pitch',
        `${dl.suggestedFilename()}: ${csvText.slice(0, 2).join(' | ')}`);
    const [dj] = await Promise.all([page.waitForEvent('download'),
        page.locator('[data-testid="download-json"]').click()]);
    const js = JSON.parse(fs.readFileSync(await dj.path(), 'utf8'));
    check(js.id === A.id && same(js.S, A.S) && js.pitch_um === sensor.pitch_um &&
        js.x_um.length === A.r, 'the JSON download is the API\'s calibration with the pitch');
    const [df] = await Promise.all([page.waitForEvent('download'),
        page.locator('[data-testid="download-fits"]').click()]);
    const fitsBytes = fs.readFileSync(await df.path());
    const fitsHead = fitsBytes.toString('latin1');
    check(fitsHead.startsWith('SIMPLE  =') && fitsBytes.length % 2880 === 0 &&
        new RegExp(`CALIBID =\\s+${A.id}\\b`).test(fitsHead) &&
        fitsHead.includes("EXTNAME = 'S       '"),
    'the FITS download is a FITS file of the calibration shown (its CALIBID, an S extension)',
    `${df.suggestedFilename()}: ${fitsBytes.length} bytes`);
    await page.screenshot({ path: path.join(SHOTS, 'pixel-1280.png'), fullPage: true });

    await page.goto(`${base}/#/scans`);
    await page.locator(`tr[data-scan-id="${scan.id}"]`).waitFor({ timeout: WAIT });
    check(await page.getByLabel('Token', { exact: true }).inputValue() === TOKEN,
        'the token is kept in the browser across page loads');

    // a long scan (991 x 991 points, so it cannot end first), cancelled from its row
    const form2 = page.locator('[data-testid="scan-form"]');
    await typeInto(form2.getByLabel('Column'), 20);
    await typeInto(form2.getByLabel('Row', { exact: true }), 20);
    await typeInto(form2.getByLabel('Area (pixels, odd)'), 33);
    await typeInto(form2.getByLabel('Step (µm)'), 0.2);
    await typeInto(form2.getByLabel('Sub-frame (pixels, odd)'), 3);
    await typeInto(form2.getByLabel('Frames per point'), 1);
    // set up by hand: the Set-up choice offers the API's words and sends the one chosen
    const setupWords = docRule(doc, 'post', '/api/scans', 'setup').enum;
    const offeredSetups = await form2.getByLabel('Set-up').locator('option')
        .evaluateAll((os) => os.map((o) => o.value));
    check(JSON.stringify(offeredSetups) === JSON.stringify(setupWords),
        'the Set-up choice offers the API\'s words', JSON.stringify(offeredSetups));
    await form2.getByLabel('Set-up').selectOption('none');
    await typeInto(form2.getByLabel('Exposure (µs)'), 2000);
    await form2.getByRole('button', { name: 'Start scan' }).click();
    const longId = (await until(async () => (await api('GET', '/api/scans')).body.items
        .find((s) => s.id !== scan.id), 'the long scan to be queued')).id;
    const long = page.locator(`tr[data-scan-id="${longId}"]`);
    const cancel = long.getByRole('button', { name: `Cancel scan #${longId}` });
    await cancel.waitFor({ timeout: WAIT });
    await cancel.click();
    await page.locator(`tr[data-scan-id="${longId}"][data-state="cancelled"]`)
        .waitFor({ timeout: WAIT });
    const cancelled = (await api('GET', `/api/scans/${longId}`)).body;
    const longJob = (await api('GET', `/api/jobs?kind=scan&scan=${longId}`)).body.items[0];
    check(longJob && longJob.params.setup === 'none' && cancelled.exposure_us === 2000,
        'the form sent "setup": "none" with the exposure typed',
        JSON.stringify([longJob?.params, cancelled.exposure_us]));
    check(longId !== scan.id && cancelled.state === 'cancelled' &&
        cancelled.points_done < cancelled.raster.points_total,
    'the Cancel button cancels a running scan', `${cancelled.state}, ` +
        `${cancelled.points_done} / ${cancelled.raster.points_total}`);
    check(await page.locator(`tr[data-scan-id="${longId}"] button`).count() === 0,
        'a cancelled scan has no Cancel button');
    await page.screenshot({ path: path.join(SHOTS, 'scans-1280.png') });
    await checkLiveZoom(base, page, api, sensor);
    await checkAdaptiveScan(base, page, api, sensor);

    // the Sensor view: a photon-transfer measurement on the simulated bench from its button, the
    // job's progress to done, the figures' table equal to the API's, the plot with every level
    await page.goto(`${base}/#/sensors/${sensor.id}`);
    await page.getByRole('button', { name: 'Measure photon transfer' }).click();
    await page.locator('[data-testid="ptc-status"][data-state="done"]')
        .waitFor({ timeout: LONG_WAIT });
    await page.locator('[data-testid="ptc-table"]').waitFor({ timeout: WAIT });
    const ptc = (await api('GET', `/api/sensors/${sensor.id}/ptc`)).body.current;
    const cell = (f) => page.locator(`[data-testid="ptc-table"] td[data-field="${f}"]`)
        .getAttribute('data-value');
    check(ptc && await cell('gain_e_per_dn') === String(ptc.gain_e_per_dn) &&
        await cell('read_noise_e') === String(ptc.read_noise_e) &&
        await cell('saturation_dn') === String(ptc.saturation_dn) &&
        await cell('dark_dn') === String(ptc.dark_dn),
    'the photon-transfer table shows the API\'s gain, read noise, saturation and dark signal',
    `${await cell('gain_e_per_dn')} vs ${ptc?.gain_e_per_dn}`);
    check(ptc && Math.abs(ptc.gain_e_per_dn / sensor.gain_e_per_dn - 1) < 0.02,
        'the measured gain is within 2 % of the simulated sensor\'s',
        `${ptc?.gain_e_per_dn} vs ${sensor.gain_e_per_dn}`);
    const pt = await plotly(page, 'ptc-plot');
    const lv = ptc.result.levels.map((l) => [l.mu - l.mu_dark, l.sigma2 - l.sigma2_dark])
        .filter(([x, y]) => x > 0 && y > 0);
    const ptcShown = [...pt.data[0].x, ...pt.data[1].x].sort((a, b) => a - b);
    const satLv = ptc.result.levels[ptc.result.saturation_level];
    check(pt.layout.xaxis.type === 'log' && pt.layout.yaxis.type === 'log' &&
        ptcShown.length === lv.length && lv.map(([x]) => x).sort((a, b) => a - b)
        .every((x, k) => near(x, ptcShown[k], 1e-12)),
    'the photon-transfer plot is log-log with a point for every level', `${ptcShown.length} of ` +
        `${lv.length}`);
    const line = pt.data[2], satTr = pt.data[3];
    check(near(line.y[1] / line.x[1], ptc.result.K, 1e-12) && satTr &&
        near(satTr.x[0], satLv.mu - satLv.mu_dark, 1e-12),
    'the plot has the fitted line (slope K) and the saturation point');
    await page.screenshot({ path: path.join(SHOTS, 'sensor-ptc-1280.png'), fullPage: true });

    // on a phone (390 x 844) no view scrolls sideways: wide tables scroll inside their box, the
    // Fit view's plots drawn (their pairs stacked)
    await page.setViewportSize({ width: 390, height: 844 });
    const views = [['#/scans', `tr[data-scan-id="${scan.id}"]`],
        [`#/scans/${scan.id}`, '[data-testid="subframe-overview"][data-state="ready"]'],
        [`#/fits/${fitId}`, '[data-testid="plot-resid"][data-state="ready"]'],
        ['#/calibrations', 'table.list tbody tr'],
        [`#/sensors/${sensor.id}/pixels/${scan.poi.col}/${scan.poi.row}`,
            '[data-testid="plot-compare"][data-state="ready"]']];
    for (const [view, ready] of views) {
        await page.goto(`${base}/${view}`);
        await page.locator(ready).first().waitFor({ timeout: WAIT });
        const w = await page.evaluate(() => [document.documentElement.scrollWidth,
            document.documentElement.clientWidth]);
        check(w[0] <= w[1], `${view} at 390 px: no sideways scrolling`, `page ${w[0]} px wide`);
        if (view === `#/scans/${scan.id}`) {
            await page.locator('[data-testid="raster-map"][data-state="ready"]')
                .waitFor({ timeout: WAIT });
        }
        const shot = view.replace(/^#\//, '').replace(/\/\d+.*$/, '') || 'scans';
        await page.screenshot({ path: path.join(SHOTS, `${shot}${/\d/.test(view) ? '-one' : ''}` +
            '-390.png'), fullPage: true });
        if (view.startsWith('#/fits/')) {
            check(await page.locator('[data-testid="plot-maps"][data-stacked="true"]').count() ===
                1 && await page.locator('[data-testid="plot-resid"][data-stacked="true"]')
                .count() === 1 && await page.locator('[data-testid="plot-selection"]' +
                '[data-stacked="true"]').count() === 1,
            'at 390 px the side-by-side plots stand one above the other');
        }
        if (view.startsWith('#/sensors/')) {
            check(await page.locator('[data-testid="plot-compare"][data-stacked="true"]')
                .count() === 1, 'at 390 px the compared maps stand one above the other');
        }
    }
    await page.setViewportSize({ width: 1280, height: 800 });
}

// The dashboard against an ipsd whose reads are closed (--read-token; api: the test's client,
// sending the write token on every request): the token form, reads and events with the token.
async function runReadClosed(context, base, api, logFile) {
    const page = await context.newPage();
    const errors = [], streams = [];
    page.on('console', (msg) => {
        if (msg.type() === 'error') errors.push(`${msg.text()} (${msg.location().url})`);
    });
    page.on('pageerror', (e) => errors.push(`uncaught: ${e.message}`));
    page.on('request', (r) => {
        if (r.url().includes('/api/events')) streams.push(r.url());
    });
    const raster = { area_px: 1, step_um: 2, sub_px: 3, frames: 1 };
    const sensor = (await api('POST', '/api/sensors', { model: 'RC-CAM', serial: 'RC-1' })).body;
    const first = (await api('POST', '/api/scans', { sensor_id: sensor.id,
        poi: { col: 10, row: 10 }, raster })).body;
    check((await api('GET', '/api/scans', undefined, false, '')).status === 401,
        'reads closed: GET /api/scans without a token is 401');

    await page.goto(`${base}/#/scans`, { timeout: LONG_WAIT });
    const prompt = page.locator('[data-testid="token-prompt"]');
    await prompt.waitFor({ timeout: WAIT });
    check(await page.locator(`tr[data-scan-id="${first.scan.id}"]`).count() === 0 &&
        await page.locator('#live').getAttribute('data-state') !== 'live',
    'reads closed: the page asks for a token, shows no scan and has no event stream');
    // a wrong token: refused, the form says so and stays
    await typeInto(prompt.getByLabel('Token', { exact: true }), 'not-a-token');
    await prompt.getByRole('button', { name: 'Use token' }).click();
    await page.locator('[data-testid="token-prompt"] .token-why', { hasText: 'refused' })
        .waitFor({ timeout: WAIT });
    check(true, 'a wrong token is refused and the form asks again');
    await typeInto(prompt.getByLabel('Token', { exact: true }), READ_TOKEN);
    await prompt.getByRole('button', { name: 'Use token' }).click();
    await page.locator(`tr[data-scan-id="${first.scan.id}"]`).waitFor({ timeout: WAIT });
    check(await prompt.count() === 0, 'with the read token the scans are read, the form gone');
    await page.locator('#live[data-state="live"]').waitFor({ timeout: WAIT });
    const before = Number(await page.locator('#live').getAttribute('data-received'));
    const second = (await api('POST', '/api/scans', { sensor_id: sensor.id,
        poi: { col: 12, row: 12 }, raster })).body;
    await page.locator(`tr[data-scan-id="${second.scan.id}"][data-state="done"]`)
        .waitFor({ timeout: LONG_WAIT });
    const after = Number(await page.locator('#live').getAttribute('data-received'));
    check(after > before, 'the event stream delivers the new scan\'s job events',
        `${before} -> ${after} events`);
    const tickets = streams.map((u) => new URL(u).searchParams.get('ticket')).filter(Boolean);
    check(tickets.length > 0 && streams.every((u) => new URL(u).pathname !== '/api/events' ||
        new URL(u).searchParams.get('ticket')),
    'the stream was opened with a ticket', streams.join(' '));
    // expected: the browser logs the refused reads (401) as failed loads
    const unexpected = errors.filter((e) => !/status of 401 /.test(e));
    check(unexpected.length === 0, 'reads closed: no console errors but the 401s',
        unexpected.join(' | '));
    await page.screenshot({ path: path.join(SHOTS, 'read-token-1280.png'), fullPage: true });
    await page.close(); // the stream ends: its request-log line is written now
    const log = await until(() => {
        const text = fs.readFileSync(logFile, 'utf8');
        return / GET \/api\/events 200 /.test(text) && text;
    }, 'the stream\'s line in the request log');
    check(!log.includes('ticket=') && tickets.every((t) => !log.includes(t)) &&
        !log.includes(READ_TOKEN), 'the request log has the stream but no ticket and no token');
}

// A running scan's raster keeps the user's zoom across the page's refreshes (Plotly.react with a
// stable uirevision): a scan of 161 x 161 points (about a minute here, cancelled after the
// check) is opened, a box is dragged on its raster with the mouse like a person zooms (a
// scripted Plotly.relayout is not a user's edit: Plotly's uirevision keeps only those), then
// the page's own refresh counter (data-updates) is waited for: the axes still show the zoomed
// box, and the figure holds more points than before (the refresh redrew it).
// An adaptive scan's Scan view: the geometry figure shows the positions the planner chose, the
// API's stored positions of the POI in the order taken (GET .../pixels/0/0?all=1), the starting
// raster apart from the batches, and why the scan stopped (its setup's adaptive member); the
// Scans list tags it "adaptive".
async function checkAdaptiveScan(base, page, api, sensor) {
    const made = await api('POST', '/api/scans', { sensor_id: sensor.id,
        poi: { col: 40, row: 20 }, setup: 'none', raster: { sub_px: 3, frames: 2 },
        strategy: { kind: 'adaptive', max_points: 34, start_grid: 5, batch: 9 } });
    check(made.status === 202 && made.body.scan.strategy?.kind === 'adaptive',
        'an adaptive scan is queued', JSON.stringify(made.body).slice(0, 300));
    const id = made.body.scan.id;
    const done = await until(async () => {
        const s = (await api('GET', `/api/scans/${id}`)).body;
        return s.state === 'done' && s;
    }, 'the adaptive scan to be done');
    await page.goto(`${base}/#/scans/${id}`);
    const geo = await plotly(page, 'scan-geometry', '[data-strategy="adaptive"]');
    const px = (await api('GET', `/api/scans/${id}/pixels/0/0?all=1`)).body;
    const marks = geo.data.filter((t) => t.mode === 'markers');
    const xs = marks.flatMap((t) => t.x), ys = marks.flatMap((t) => t.y);
    const order = marks.flatMap((t) => t.customdata);
    const same = (a, b) => a.length === b.length && a.every((v, k) => near(v, b[k], 1e-12));
    check(xs.length === done.points_done && same(xs, px.x_um) && same(ys, px.y_um) &&
        same(order, px.x_um.map((_, k) => k)) && marks[0].x.length === 25,
    'the adaptive scan\'s geometry shows its stored positions in the order taken, the 25 of ' +
        'the starting raster first', `${xs.length} markers, ${done.points_done} points`);
    const title = await page.locator('[data-testid="scan-geometry"]').evaluate((g) =>
        g.closest('figure')?.textContent ?? '');
    check(title.includes(`stopped (${done.setup.adaptive.stop}) at ${done.points_done} points`),
        'the figure says why the adaptive scan stopped', title.slice(0, 200));
    const facts = await page.locator('dl.facts').textContent();
    check(facts.includes('Adaptive') && facts.includes(`batches of 9`) &&
        facts.includes(`stopped (${done.setup.adaptive.stop}) at ${done.points_done} points`),
    'the summary states the adaptive strategy and its stop instead of a raster', facts);
    await page.locator('[data-testid="scan-geometry"]').scrollIntoViewIfNeeded();
    await page.screenshot({ path: path.join(SHOTS, 'scan-adaptive-1280.png') });
    // the Scans list tags it, from the list item's strategy, and no raster scan
    await page.goto(`${base}/#/scans`);
    const tag = page.locator(`tr[data-scan-id="${id}"] .tag.adaptive`);
    await tag.waitFor({ timeout: WAIT });
    const tagged = await page.locator('tr[data-scan-id] .tag.adaptive').count();
    check(await tag.textContent() === 'adaptive' && tagged === 1,
        'the scan list tags the adaptive scan, and it alone', `${tagged} tagged`);
}

async function checkLiveZoom(base, page, api, sensor) {
    const step = (5 * sensor.pitch_um) / 160; // area 5 pixels: 161 points per axis
    const made = await api('POST', '/api/scans', { sensor_id: sensor.id,
        poi: { col: 30, row: 20 }, optics: { wavelength_nm: 550, na: 0.25 },
        raster: { area_px: 5, step_um: step, sub_px: 3, frames: 1 }, scene: 'paperlike' });
    check(made.status === 202, 'a long scan for the live raster is queued', JSON.stringify(made));
    const id = made.body.scan.id;
    await page.goto(`${base}/#/scans/${id}`);
    const sel = '[data-testid="raster-map"][data-state="ready"]';
    await page.locator(`${sel}[data-pixel="0,0"]`).waitFor({ timeout: LONG_WAIT });
    const axes = () => page.$eval('[data-testid="raster-map"]', (g) => ({
        x: [...g._fullLayout.xaxis.range], y: [...g._fullLayout.yaxis.range],
        updates: Number(g.dataset.updates || 0), points: Number(g.dataset.points),
        state: g.dataset.state }));
    const before = await axes();
    // drag a box over the middle of the plot area, from 35 % to 60 % of each axis
    await page.locator('[data-testid="raster-map"]').scrollIntoViewIfNeeded();
    const box = await page.$eval('[data-testid="raster-map"]', (g) => {
        const fl = g._fullLayout, b = g.getBoundingClientRect();
        const at = (ax, f, off) => off + ax._offset + f * ax._length;
        return [at(fl.xaxis, 0.35, b.left), at(fl.yaxis, 0.35, b.top), at(fl.xaxis, 0.6, b.left),
            at(fl.yaxis, 0.6, b.top)];
    });
    await page.mouse.move(box[0], box[1]);
    await page.mouse.down();
    await page.mouse.move(box[2], box[3], { steps: 8 });
    await page.mouse.up();
    const span = (r) => Math.abs(r[1] - r[0]);
    const zoomed = await until(async () => {
        const a = await axes();
        return span(a.x) < 0.8 * span(before.x) && a;
    }, 'the drag to zoom the raster');
    // the page's next refresh of the figure (new points stored), whatever its cause
    await page.waitForFunction(([n, p]) => {
        const g = document.querySelector('[data-testid="raster-map"]');
        return g && Number(g.dataset.updates || 0) > n && Number(g.dataset.points) > p &&
            g.dataset.state === 'ready';
    }, [zoomed.updates, zoomed.points], { timeout: LONG_WAIT, polling: 100 });
    const after = await axes();
    const same = (a, b) => a.every((v, k) => near(v, b[k], 1e-9));
    check(same(after.x, zoomed.x) && same(after.y, zoomed.y) && after.points > zoomed.points,
        'a running scan\'s raster keeps the user\'s zoom when the page refreshes it',
        JSON.stringify({ before, zoomed, after }));
    // the zoom radio still sets the axes (a new uirevision), then the refreshes keep that
    await page.locator('[data-testid="zoom-pixel"]').check();
    const px = await until(async () => {
        const a = await axes();
        return a.x[1] - a.x[0] < 1.2 * sensor.pitch_um && a.x[0] < 0 && a;
    }, 'the zoom to the pixel');
    check(px.x[1] > sensor.pitch_um, 'the "the pixel" zoom still applies to a live raster',
        JSON.stringify(px));
    const cancel = await api('POST', `/api/scans/${id}/cancel`);
    await until(async () => (await api('GET', `/api/scans/${id}`)).body.state === 'cancelled',
        'the live-raster scan to be cancelled');
    check(cancel.status < 300, 'the live-raster scan is cancelled', JSON.stringify(cancel));
}

// ---- main ----

const tmp = fs.mkdtempSync(path.join(os.tmpdir(), 'ipsd-web-'));
fs.mkdirSync(SHOTS, { recursive: true });
const watchdog = setTimeout(() => {
    console.log('not ok - the test took over 420 s');
    process.exit(1);
}, 420000);
let daemon = null, daemon2 = null, context = null;
const consoleErrors = [];
try {
    daemon = await startIpsd(tmp);
    const base = `http://127.0.0.1:${daemon.port}`;
    // the test's own client: fetch, with the token on writes unless told otherwise
    const api = async (method, p, body, raw, token = TOKEN) => {
        const headers = body ? { 'Content-Type': 'application/json' } : {};
        if (method !== 'GET' && token) headers.Authorization = `Bearer ${token}`;
        const res = await fetch(base + p, { method, headers,
            body: body ? JSON.stringify(body) : undefined });
        const text = await res.text();
        record(method, p, res.status, res.headers.get('content-type'), text,
            body ? JSON.stringify(body) : null);
        return { status: res.status, body: raw ? text : JSON.parse(text) };
    };
    context = await chromium.launchPersistentContext(path.join(tmp, 'profile'), {
        executablePath: CHROMIUM,
        headless: true,
        viewport: { width: 1280, height: 800 },
        args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
            '--disable-background-networking', '--disable-component-update', '--disable-sync',
            '--disable-dev-shm-usage'],
    });
    const page = context.pages()[0] || await context.newPage();
    page.setDefaultTimeout(WAIT);
    page.on('console', (msg) => {
        if (msg.type() === 'error') consoleErrors.push(`${msg.text()} (${msg.location().url})`);
    });
    page.on('pageerror', (e) => consoleErrors.push(`uncaught: ${e.message}`));
    page.on('response', (res) => {
        const url = new URL(res.url());
        if (!RECORD_FILE || url.origin !== base || !url.pathname.startsWith('/api/') ||
            url.pathname.startsWith('/api/events')) return;
        const req = res.request();
        const done = res.text().then((text) => record(req.method(), url.pathname + url.search,
            res.status(), res.headers()['content-type'], text, req.postData()))
            .catch(() => {}) // a body the page dropped (navigated away): nothing to check
            .finally(() => pendingRecords.delete(done));
        pendingRecords.add(done);
    });
    await run(base, page, api);
    // expected: the browser logs the 401 and the 422 of the refused requests as failed loads
    const expected = (e) => /status of 422 .*\/api\/scans(\/\d+\/fits)?\)$/.test(e) ||
        /status of 401 .*\/api\/sensors\)$/.test(e);
    const unexpected = consoleErrors.filter((e) => !expected(e));
    consoleErrors.filter(expected).forEach((e) => console.log(`# expected: ${e}`));
    check(unexpected.length === 0, 'no console errors', unexpected.join(' | '));

    // the second ipsd: reads closed
    const tmp2 = path.join(tmp, 'read-closed');
    fs.mkdirSync(tmp2);
    fs.writeFileSync(path.join(tmp2, 'read-token'), `${READ_TOKEN}\n`);
    daemon2 = await startIpsd(tmp2, ['--read-token', path.join(tmp2, 'read-token')]);
    const base2 = `http://127.0.0.1:${daemon2.port}`;
    const api2 = async (method, p, body, raw, token = TOKEN) => {
        const headers = body ? { 'Content-Type': 'application/json' } : {};
        if (token) headers.Authorization = `Bearer ${token}`;
        const res = await fetch(base2 + p, { method, headers,
            body: body ? JSON.stringify(body) : undefined });
        return { status: res.status, body: raw ? await res.text() : await res.json() };
    };
    await runReadClosed(context, base2, api2, path.join(tmp2, 'ipsd.log'));
} catch (e) {
    failed++;
    console.log(`not ok - ${e.stack || e}`);
    const shot = path.join(SHOTS, 'failure.png');
    await context?.pages()[0]?.screenshot({ path: shot, fullPage: true }).catch(() => {});
    console.log(`# screenshot of the failure: ${shot}`);
    if (fs.existsSync(path.join(tmp, 'ipsd.log'))) {
        const log = fs.readFileSync(path.join(tmp, 'ipsd.log'), 'utf8');
        console.log(`# ipsd log:\n${log.slice(-3000)}`);
    }
} finally {
    await Promise.allSettled([...pendingRecords]);
    if (RECORD_FILE) console.log(`# ${recorded} API answers recorded in ${RECORD_FILE}`);
    await context?.close().catch(() => {});
    await stopIpsd(daemon, path.join(tmp, 'ipsd.log'));
    await stopIpsd(daemon2, path.join(tmp, 'read-closed', 'ipsd.log'));
    fs.rmSync(tmp, { recursive: true, force: true });
    clearTimeout(watchdog);
}
console.log(`# screenshots: ${SHOTS}`);
console.log(`${passed} passed, ${failed} failed`);
process.exit(failed ? 1 : 0);
