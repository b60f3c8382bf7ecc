// End-to-end check of hwr-ground's viewer in headless Debian Chromium, driven by playwright-core
// (no browser download: executablePath is the Debian binary). Used by
// tests/apps/test_hwr_ground_viewer_browser.cpp and by toolchain/demo.sh (--screenshot-only).
//
//   node viewer_e2e.mjs --url URL --screenshot FILE [--timeout-s 120] [--min-segments 2]
//                       [--min-detections 1] [--screenshot-only]
//
// Loads the page, waits until it has drawn at least min-segments segments and min-detections
// detections; then (unless --screenshot-only) rejects the first proposed or confirmed detection,
// waits until the robot acknowledged the command and republished the detection as rejected, reloads
// the page and checks that it still shows both; finally saves a screenshot. Prints key=value lines
// (e2e_segments, e2e_detections, e2e_rejected_id, e2e_command_id, e2e_ok=1) and exits 0, or prints
// e2e_error=... with the page's console errors and exits 1.
import { mkdtempSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { chromium } from 'playwright-core';

function parse_args(argv) {
  const args = { timeout_s: 120, min_segments: 2, min_detections: 1, screenshot_only: false };
  for (let i = 0; i < argv.length; ++i) {
    const a = argv[i];
    const value = () => {
      if (i + 1 >= argv.length) throw new Error(`${a} needs a value`);
      return argv[++i];
    };
    if (a === '--url') args.url = value();
    else if (a === '--screenshot') args.screenshot = value();
    else if (a === '--timeout-s') args.timeout_s = Number(value());
    else if (a === '--min-segments') args.min_segments = Number(value());
    else if (a === '--min-detections') args.min_detections = Number(value());
    else if (a === '--screenshot-only') args.screenshot_only = true;
    else throw new Error(`unknown argument ${a}`);
  }
  if (!args.url || !args.screenshot) throw new Error('--url and --screenshot are required');
  return args;
}

// What headless Chromium needs here: no sandbox (root), no GPU (WebGL through SwiftShader), and no
// background networking (this machine's network is closed).
const CHROMIUM_ARGS = [
  '--no-sandbox',
  '--disable-gpu',
  '--use-angle=swiftshader',
  '--enable-unsafe-swiftshader',
  '--disable-quic',
  '--no-first-run',
  '--disable-background-networking',
  '--disable-component-update',
  '--disable-sync',
];

async function wait_drawn(page, args, deadline_ms) {
  await page.waitForFunction(
    ([segments, detections]) =>
      Number(document.body.dataset.segmentsDrawn) >= segments &&
      Number(document.body.dataset.detectionsDrawn) >= detections,
    [args.min_segments, args.min_detections],
    { timeout: Math.max(1000, deadline_ms - Date.now()), polling: 250 },
  ).catch((error) => {
    if (error.name !== 'TimeoutError') throw error;
    throw new Error(`the page did not draw ${args.min_segments} segments and ${args.min_detections} detections in time`);
  });
}

async function main() {
  const args = parse_args(process.argv.slice(2));
  const deadline = Date.now() + 1000 * args.timeout_s;
  // A browser that hangs (at launch, in a screenshot) must not hang the caller.
  setTimeout(() => {
    console.log(`e2e_error=no result after ${args.timeout_s + 60} s`);
    process.exit(1);
  }, 1000 * (args.timeout_s + 60)).unref();
  const profile = mkdtempSync(join(tmpdir(), 'hwr-viewer-e2e-'));
  const errors = [];
  const context = await chromium.launchPersistentContext(profile, {
    executablePath: process.env.HWR_CHROMIUM || '/usr/bin/chromium',
    headless: true,
    args: CHROMIUM_ARGS,
    viewport: { width: 1280, height: 800 },
  });
  try {
    const page = context.pages()[0] ?? (await context.newPage());
    page.on('console', (m) => m.type() === 'error' && errors.push(m.text()));
    page.on('pageerror', (e) => errors.push(e.message));
    await page.goto(args.url);
    await wait_drawn(page, args, deadline);
    const result = {
      e2e_segments: await page.evaluate(() => document.body.dataset.segmentsDrawn),
      e2e_detections: await page.evaluate(() => document.body.dataset.detectionsDrawn),
    };
    if (!args.screenshot_only) {
      const row = page.locator('[data-detection-id][data-state="proposed"], [data-detection-id][data-state="confirmed"]').first();
      const left = () => Math.max(1000, deadline - Date.now());
      const id = await row.getAttribute('data-detection-id', { timeout: left() });
      // A click can be lost (e.g. the list changed between mouse down and up): then it is repeated.
      let response = null;
      for (let attempt = 0; attempt < 3 && response == null; ++attempt) {
        const posted = page
          .waitForResponse((r) => r.url().includes('/api/command') && r.request().method() === 'POST', { timeout: 10000 })
          .catch(() => null);
        await page.locator(`[data-detection-id="${id}"] button[data-action="reject"]`).click({ timeout: left() });
        response = await posted;
      }
      if (response == null) throw new Error(`clicking Reject of detection ${id} sent no command`);
      const answer = await response.json().catch(() => ({}));
      if (!response.ok()) throw new Error(`POST /api/command answered ${response.status()}: ${answer.error ?? ''}`);
      const command_id = String(answer.command_id);
      const acknowledged = `[data-command-id="${command_id}"][data-state="accepted"]`;
      const rejected = `[data-detection-id="${id}"][data-state="rejected"]`;
      // Until the robot acknowledged the command and republished the detection as rejected; a
      // refusal ends the wait with the robot's reason.
      const outcome = await page.waitForFunction(
        ([command, detection]) => {
          const c = document.querySelector(`[data-command-id="${command}"]`);
          if (c?.dataset.state === 'refused') return `refused: ${c.textContent.trim()}`;
          const d = document.querySelector(`[data-detection-id="${detection}"]`);
          return c?.dataset.state === 'accepted' && d?.dataset.state === 'rejected' ? 'ok' : null;
        },
        [command_id, id],
        { timeout: left(), polling: 250 },
      );
      const result_text = await outcome.jsonValue();
      if (result_text !== 'ok') throw new Error(`command ${command_id} (reject ${id}) ${result_text}`);
      // A reload shows the same: the page holds nothing the ground station does not.
      await page.reload();
      await wait_drawn(page, args, deadline);
      await page.waitForSelector(acknowledged, { timeout: left() });
      await page.waitForSelector(rejected, { timeout: left() });
      result.e2e_rejected_id = id;
      result.e2e_command_id = command_id;
    }
    await page.waitForTimeout(500);  // one more poll and render after the last change
    await page.screenshot({ path: args.screenshot, fullPage: true });
    for (const [k, v] of Object.entries(result)) console.log(`${k}=${v}`);
    console.log('e2e_ok=1');
  } catch (error) {
    console.log(`e2e_error=${String(error.message).split('\n')[0]}`);
    const seen = await context.pages()[0]?.evaluate(() => ({
      ...document.body.dataset,
      connection: document.getElementById('connection')?.textContent,
      view: document.getElementById('view-message')?.textContent,
    })).catch(() => null);
    if (seen) console.log(`e2e_page=${JSON.stringify(seen)}`);
    for (const e of errors) console.log(`e2e_console_error=${e.split('\n')[0]}`);
    process.exitCode = 1;
  } finally {
    await context.close();
    rmSync(profile, { recursive: true, force: true });
  }
}

main().catch((error) => {
  console.log(`e2e_error=${error.message}`);
  process.exitCode = 1;
});
