// Opens the page in headless Chromium (puppeteer-core, the system's browser), waits for
// window.result, and writes it and a screenshot. Usage: node driver.mjs PAGE_URL OUT_DIR
import puppeteer from "puppeteer-core";
import { writeFileSync } from "node:fs";

const [url, out] = process.argv.slice(2);
const browser = await puppeteer.launch({
  executablePath: process.env.CHROMIUM || "/usr/bin/chromium",
  headless: true,
  args: ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
         "--allow-file-access-from-files", "--ignore-gpu-blocklist"],
});
try {
  const page = await browser.newPage();
  const log = [];
  page.on("console", (m) => log.push(`${m.type()}: ${m.text()}`));
  page.on("pageerror", (e) => log.push(`pageerror: ${e}`));
  page.on("requestfailed", (r) => log.push(`failed: ${r.url()} ${r.failure()?.errorText}`));
  await page.setViewport({ width: 512, height: 512 });
  await page.goto(url);
  await page.waitForFunction("window.result !== undefined", { timeout: 240000, polling: 200 });
  const result = await page.evaluate("window.result");
  result.log = log;
  await page.screenshot({ path: `${out}/screenshot.png` });
  writeFileSync(`${out}/result.json`, JSON.stringify(result, null, 1));
} finally {
  await browser.close();
}
