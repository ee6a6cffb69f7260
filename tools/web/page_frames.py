"""Draws frames of an exported glassbake site in headless Chromium and reads the canvas back.

    python3 tools/web/page_frames.py --url http://127.0.0.1:8000/ --draws draws.json --out DIR

draws.json is a list of {"view": {"azimuth", "elevation", "distance"}, "values": [...]}; for
draw i the page's canvas is written to DIR/frame_i.rgba (width x height x 4 bytes, rows from
the top), the frame read back from the GPU to DIR/frame_i.gpu.rgba, and DIR/result.json holds the page's size, adapter, time to its first frame and each
frame's time. The page is driven through ChromeDriver's WebDriver endpoint (Debian's
chromium and chromium-driver) with Chromium's own SwiftShader Vulkan driver where no GPU is
(set VK_ICD_FILENAMES to /usr/lib/chromium/vk_swiftshader_icd.json). Exits 3 with the page's
message when it reports an error (no WebGPU, a file it could not open).
"""
import argparse
import json
import os
import socket
import subprocess
import sys
import time
import urllib.request

CHROMIUM_FLAGS = [
    "--headless=new", "--no-sandbox", "--enable-unsafe-webgpu", "--use-angle=vulkan", "--enable-features=Vulkan",
    "--use-vulkan=native", "--disable-background-networking", "--disable-component-update", "--disable-sync",
    "--no-first-run", "--disable-quic", "--window-size=900,900",
]


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class WebDriver:
    def __init__(self, port):
        self.base = f"http://127.0.0.1:{port}"

    def call(self, method, path, body=None, timeout=300):
        data = None if body is None else json.dumps(body).encode()
        request = urllib.request.Request(self.base + path, method=method, data=data, headers={"Content-Type": "application/json"})
        with urllib.request.urlopen(request, timeout=timeout) as response:
            return json.loads(response.read())["value"]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--url", required=True)
    parser.add_argument("--draws", required=True)
    parser.add_argument("--out", required=True)
    parser.add_argument("--chromium", default="/usr/bin/chromium")
    parser.add_argument("--chromedriver", default="chromedriver")
    parser.add_argument("--timeout", type=float, default=240.0, help="seconds to wait for the page's first frame")
    args = parser.parse_args()
    draws = json.load(open(args.draws))
    os.makedirs(args.out, exist_ok=True)

    port = free_port()
    driver_process = subprocess.Popen([args.chromedriver, f"--port={port}"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    driver = WebDriver(port)
    try:
        for _ in range(100):
            try:
                driver.call("GET", "/status")
                break
            except OSError:
                time.sleep(0.1)
        options = {"binary": args.chromium, "args": CHROMIUM_FLAGS}
        capabilities = {"capabilities": {"alwaysMatch": {"goog:chromeOptions": options, "goog:loggingPrefs": {"browser": "ALL"}}}}
        session = driver.call("POST", "/session", capabilities)["sessionId"]
        try:
            driver.call("POST", f"/session/{session}/timeouts", {"script": int(args.timeout * 1000)})
            driver.call("POST", f"/session/{session}/url", {"url": args.url})
            deadline = time.time() + args.timeout
            state = None
            while time.time() < deadline:
                state = driver.call("POST", f"/session/{session}/execute/sync", {
                    "script": "const g = window.glassbake; return g ? (g.error ? {error: g.error} : {ready: !!g.site}) : null;", "args": []})
                if state and (state.get("error") or state.get("ready")):
                    break
                time.sleep(0.25)
            if not state or state.get("error"):
                print(f"the page reported: {state.get('error') if state else 'nothing within the timeout'}", file=sys.stderr)
                for entry in driver.call("POST", f"/session/{session}/se/log", {"type": "browser"}):
                    print(f"  console: {entry.get('message', '')[:2000]}", file=sys.stderr)
                sys.exit(3)
            info = driver.call("POST", f"/session/{session}/execute/sync", {
                "script": "const g = window.glassbake; return {size: g.site.resolution, first_frame_ms: g.firstFrameMs, first_draw_ms: g.firstFrameDrawMs, stats: document.getElementById('stats').textContent};",
                "args": []})
            frames = []
            for i, draw in enumerate(draws):
                result = driver.call("POST", f"/session/{session}/execute/async", {
                    "script": "const done = arguments[arguments.length - 1]; const g = window.glassbake;"
                              "g.draw(arguments[0], true).then(async (ms) => done({ms, canvas: g.readCanvas(), frame: await g.readFrame()}), (e) => done({error: String(e)}));",
                    "args": [draw]})
                if result.get("error"):
                    print(f"draw {i}: {result['error']}", file=sys.stderr)
                    sys.exit(3)
                with open(os.path.join(args.out, f"frame_{i}.rgba"), "wb") as f:
                    f.write(bytes(result["canvas"]))
                with open(os.path.join(args.out, f"frame_{i}.gpu.rgba"), "wb") as f:
                    f.write(bytes(result["frame"]))
                frames.append({"ms": result["ms"]})
            # Frame time once warm: the same view drawn again a few times.
            warm = [driver.call("POST", f"/session/{session}/execute/async", {
                "script": "const done = arguments[arguments.length - 1]; window.glassbake.draw({}).then(done);", "args": []}) for _ in range(5)]
            info.update(frames=frames, warm_frame_ms=sorted(warm)[len(warm) // 2])
            json.dump(info, open(os.path.join(args.out, "result.json"), "w"), indent=1)
        finally:
            driver.call("DELETE", f"/session/{session}")
    finally:
        driver_process.kill()


if __name__ == "__main__":
    main()
