#!/usr/bin/python3
# SPDX-License-Identifier: MIT
# Runs examples/spec_client.py against a scripted fake daemon that follows
# PROTOCOL.md (a ROUTER socket; every request and every reply checked against
# schemas/). Covers: list, a scan with events and multi-chunk fetches, a scan
# whose events are all lost (client must poll status), a failed scan, and an
# error reply. Needs Debian's python3-zmq and python3-jsonschema.
import json
import os
import pathlib
import subprocess
import sys
import tempfile
import threading

import zmq
from jsonschema import Draft202012Validator, RefResolver

PROTO = pathlib.Path(__file__).resolve().parent.parent
CLIENT = PROTO / "examples" / "spec_client.py"

STORE = {}
for p in (PROTO / "schemas").glob("*.schema.json"):
    s = json.loads(p.read_text())
    STORE[s["$id"]] = s


def validator(name):
    s = STORE["https://procam.invalid/proto/1/" + name]
    return Draft202012Validator(s, resolver=RefResolver.from_schema(s, store=STORE))


REQUEST, REPLY, EVENT = (validator(n) for n in
                         ("request.schema.json", "reply.schema.json", "event.schema.json"))

PLUGINS = [{"name": "structured-light", "version": "0.1.0", "file": "procam-structured-light.so",
            "methods": [{"name": "gray", "description": "Gray code", "patterns": 22,
                         "params": [{"name": "bits", "type": "int", "default": 10, "min": 1,
                                     "max": 11, "description": "code bits"}]},
                        {"name": "fail", "description": "always fails", "patterns": 1,
                         "params": []}]}]
FILES = {"depth_mm.exr": os.urandom(2 * 65536 + 123),   # several chunks at --chunk 65536
         "points.ply": os.urandom(1000),
         "empty.bin": b""}


class FakeDaemon(threading.Thread):
    """Single-threaded ROUTER loop answering from a script. Records problems in
    self.problems instead of raising, so the test can report them."""

    def __init__(self):
        super().__init__(daemon=True)
        self.sock = zmq.Context.instance().socket(zmq.ROUTER)
        self.port = self.sock.bind_to_random_port("tcp://127.0.0.1")
        self.stop = threading.Event()
        self.problems, self.requests = [], []
        self.scans = {}

    def send(self, envelope, msg, data=None, validate=REPLY):
        errs = [e.message for e in validate.iter_errors(msg)]
        if errs:
            self.problems.append(f"fake daemon sends an invalid message {msg}: {errs}")
        frames = envelope + [json.dumps(msg).encode()]
        if data is not None:
            frames.append(data)
        self.sock.send_multipart(frames)

    def reply(self, env, req, **fields):
        self.send(env, {"procam": 1, "id": req["id"], "type": req["type"], "ok": True, **fields})

    def error(self, env, req, code, message, hint=""):
        self.send(env, {"procam": 1, "id": req.get("id"), "type": "error", "ok": False,
                        "error": {"code": code, "message": message, "hint": hint}})

    def event(self, env, scan, event, **fields):
        msg = {"procam": 1, "type": "event", "scan_id": scan["scan_id"], "seq": scan["seq"],
               "event": event, **fields}
        scan["seq"] += 1
        if not scan["drop_events"]:
            self.send(env, msg, validate=EVENT)

    def run(self):
        while not self.stop.is_set():
            if not self.sock.poll(50):
                continue
            frames = self.sock.recv_multipart()
            # [routing id, empty, body] (PROTOCOL.md 1.2)
            if len(frames) != 3 or frames[1] != b"":
                self.problems.append(f"client sent bad framing: {frames!r:.200}")
                continue
            env, req = frames[:2], json.loads(frames[2])
            self.requests.append(req)
            errs = [e.message for e in REQUEST.iter_errors(req)]
            if errs:
                self.problems.append(f"client sent an invalid request {req}: {errs}")
                self.error(env, req, "bad_message", "; ".join(errs))
                continue
            getattr(self, "on_" + req["type"])(env, req)

    def on_hello(self, env, req):
        self.reply(env, req, version=1, daemon="fake 0", rig="sim-default",
                   capabilities=["events", "fetch", "future-thing"])

    def on_list_plugins(self, env, req):
        self.reply(env, req, plugins=PLUGINS, rejected=[
            {"file": "procam-old.so", "error": {"code": "abi_mismatch", "message": "ABI 0",
                                                "hint": "rebuild"}}])

    def on_scan(self, env, req):
        if req["plugin"] != "structured-light":
            return self.error(env, req, "not_found", f"plugin '{req['plugin']}' is not loaded",
                              "run list_plugins")
        failed = req["method"] == "fail"
        scan = {"scan_id": f"scan-{len(self.scans) + 1}", "seq": 0, "req": req,
                "drop_events": req.get("rig_options", {}).get("drop_events", False),
                "state": "failed" if failed else "done"}
        self.scans[scan["scan_id"]] = scan
        self.reply(env, req, scan_id=scan["scan_id"], state="queued", queue_position=0,
                   unknown_future_field={"x": 1})
        # Run the whole scan at once; the client cannot tell.
        self.event(env, scan, "state", state="capturing")
        for i in range(3):
            self.event(env, scan, "progress", stage="capture", round=1, done=i + 1, total=3)
        scan["seq"] += 1  # a lost event: the client must cope with the gap
        self.event(env, scan, "future_event_kind", whatever=1)
        self.event(env, scan, "log", level="info", message="hello from the fake")
        if failed:
            self.event(env, scan, "state", state="failed",
                       error={"code": "plugin_error", "message": "fake failure", "hint": ""})
        else:
            self.event(env, scan, "state", state="decoding")
            self.event(env, scan, "progress", stage="decode", round=1, done=1, total=1)
            self.event(env, scan, "state", state="done")

    def manifest(self, scan):
        req = scan["req"]
        failed = scan["state"] == "failed"
        files = [] if failed else [{"name": n, "size_bytes": len(b)} for n, b in FILES.items()]
        return {"procam": 1, "scan_id": scan["scan_id"], "state": scan["state"],
                "plugin": req["plugin"], "method": req["method"], "params": req.get("params", {}),
                "label": req.get("label", ""), "rig": {"name": "sim-default", "state": {}},
                "created_utc": "2025-03-01T12:00:00.000Z",
                "finished_utc": "2025-03-01T12:00:01.000Z",
                "plan": {"rounds": [{"note": "", "frames": 3}], "patterns": 3},
                "timing_ms": {"capture": 1.0, "decode": 1.0, "write": 1.0, "total": 3.0},
                "outputs": [] if failed else [
                    {"name": "valid_fraction", "kind": "scalar", "unit": "", "description": "v",
                     "value": 0.75}],
                "previews": [], "files": files,
                "error": {"code": "plugin_error", "message": "fake failure", "hint": ""}
                if failed else None}

    def on_status(self, env, req):
        scan = self.scans.get(req.get("scan_id"))
        if scan is None:
            return self.error(env, req, "not_found", "no such scan")
        self.reply(env, req, scan={
            "scan_id": scan["scan_id"], "state": scan["state"], "plugin": "structured-light",
            "method": scan["req"]["method"], "label": "", "created_utc": "2025-03-01T12:00:00Z",
            "finished_utc": "2025-03-01T12:00:01Z",
            "progress": {"stage": "write", "round": 1, "done": 1, "total": 1},
            "error": self.manifest(scan)["error"]})

    def on_result(self, env, req):
        scan = self.scans[req["scan_id"]]
        self.reply(env, req, scan_id=scan["scan_id"], state=scan["state"],
                   manifest=self.manifest(scan))

    def on_fetch(self, env, req):
        data = FILES.get(req["file"])
        if data is None:
            return self.error(env, req, "not_found", f"no file {req['file']}")
        off, n = req.get("offset", 0), req.get("max_bytes", 1 << 20)
        chunk = data[off:off + n]
        self.send(env, {"procam": 1, "id": req["id"], "type": "fetch", "ok": True,
                        "scan_id": req["scan_id"], "file": req["file"], "offset": off,
                        "bytes": len(chunk), "size": len(data), "eof": off + len(chunk) == len(data)},
                  data=chunk)


def run_client(port, *args):
    cmd = [sys.executable, "-B", str(CLIENT), "--endpoint", f"tcp://127.0.0.1:{port}",
           "--timeout", "5", *args]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
    print(f"$ spec_client.py {' '.join(args)}  -> {p.returncode}\n{p.stdout}{p.stderr}")
    return p


def main():
    failures = []

    def check(cond, what):
        if not cond:
            failures.append(what)
            print("FAIL:", what)

    fake = FakeDaemon()
    fake.start()
    try:
        with tempfile.TemporaryDirectory() as tmp:
            p = run_client(fake.port, "list")
            check(p.returncode == 0, "list exits 0")
            check("structured-light 0.1.0" in p.stdout and "bits (int, default 10" in p.stdout,
                  "list prints plugins, methods and params")
            check("abi_mismatch" in p.stderr, "list reports rejected plugins")

            out = os.path.join(tmp, "ok")
            p = run_client(fake.port, "scan", "--plugin", "structured-light", "--method", "gray",
                           "--param", "bits=10", "--param", "name=abc", "--rig-option",
                           "scene=tilted-box", "--label", "t", "--out", out, "--chunk", "65536")
            check(p.returncode == 0, "scan exits 0")
            check("capture round 1: 3/3" in p.stdout, "scan prints progress")
            check("missed events" in p.stdout, "scan notices the seq gap")
            check("state: done" in p.stdout, "scan prints the final state")
            for name, data in FILES.items():
                path = os.path.join(out, name)
                check(os.path.exists(path) and pathlib.Path(path).read_bytes() == data,
                      f"fetched {name} intact")
            check(not any(n.endswith(".part") for n in os.listdir(out)), "no partial files left")
            manifest = json.loads(pathlib.Path(out, "manifest.json").read_text())
            check(manifest["state"] == "done", "manifest.json written")
            scan_req = next(r for r in fake.requests if r["type"] == "scan")
            check(scan_req["params"] == {"bits": 10, "name": "abc"} and scan_req["events"] is True
                  and scan_req["rig_options"] == {"scene": "tilted-box"},
                  f"scan request fields typed from k=v: {scan_req}")
            fetches = [r for r in fake.requests if r["type"] == "fetch"
                       and r["file"] == "depth_mm.exr"]
            check([r["offset"] for r in fetches] == [0, 65536, 131072],
                  "depth_mm.exr fetched in 64 KiB chunks")

            p = run_client(fake.port, "scan", "--plugin", "structured-light", "--method", "gray",
                           "--rig-option", "drop_events=true", "--out", os.path.join(tmp, "quiet"),
                           "--poll-interval", "0.3")
            check(p.returncode == 0 and "(from status)" in p.stdout,
                  "without events the client polls status and finishes")

            p = run_client(fake.port, "scan", "--plugin", "structured-light", "--method", "fail",
                           "--out", os.path.join(tmp, "failed"))
            check(p.returncode == 1 and "plugin_error: fake failure" in p.stderr,
                  "a failed scan exits 1 with its error")
            check(os.path.exists(os.path.join(tmp, "failed", "manifest.json")),
                  "a failed scan still writes its manifest")

            p = run_client(fake.port, "scan", "--plugin", "nope", "--method", "gray",
                           "--out", os.path.join(tmp, "nope"))
            check(p.returncode == 1 and "not_found" in p.stderr, "an error reply exits 1")

            p = run_client(fake.port, "scan", "--plugin", "x", "--method", "y")
            check(p.returncode == 2, "missing --out is a usage error")
    finally:
        fake.stop.set()
        fake.join(5)
    for problem in fake.problems:
        failures.append(problem)
        print("FAIL:", problem)
    if failures:
        print(f"{len(failures)} failure(s)")
        return 1
    print("ok: spec_client.py follows PROTOCOL.md against the fake daemon")
    return 0


if __name__ == "__main__":
    sys.exit(main())
