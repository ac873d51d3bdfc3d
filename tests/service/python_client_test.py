#!/usr/bin/python3
# SPDX-License-Identifier: MIT
# End to end: clients/python/procam_client.py and its example script against
# a real procamd (plain and with CURVE), on private ipc:// endpoints.
# Run with Debian's /usr/bin/python3 (python3-zmq).
import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "clients", "python"))
from procam_client import Client, ProcamError, Timeout, keypair  # noqa: E402

failures = []


def check(cond, what):
    if not cond:
        failures.append(what)
        print("FAIL:", what, flush=True)


class Daemon:
    def __init__(self, procamd, config, plugins, tmp, name, extra_config=None):
        self.dir = os.path.join(tmp, name)
        os.makedirs(self.dir)
        cfg = config
        if extra_config:
            with open(config, encoding="utf-8") as f:
                j = json.load(f)
            base = os.path.dirname(os.path.abspath(config))
            j["rig"] = os.path.join(base, j["rig"])
            j["scene_dirs"] = [os.path.join(base, d) for d in j.get("scene_dirs", [])]
            j.update(extra_config)
            cfg = os.path.join(self.dir, "procamd.json")
            with open(cfg, "w", encoding="utf-8") as f:
                json.dump(j, f)
        self.endpoint = "ipc://" + os.path.join(self.dir, "procamd.sock")
        self.log = open(os.path.join(self.dir, "procamd.log"), "w")
        self.proc = subprocess.Popen(
            [procamd, "--config", cfg, "--endpoint", self.endpoint,
             "--results", os.path.join(self.dir, "results"), "--plugins", plugins],
            stdout=self.log, stderr=subprocess.STDOUT)

    def wait_ready(self, **keys):
        for _ in range(100):
            if self.proc.poll() is not None:
                return False
            try:
                with Client(self.endpoint, timeout=0.5, **keys) as c:
                    c.ping()
                    return True
            except Timeout:
                pass
        return False

    def stop(self):
        self.proc.send_signal(signal.SIGTERM)
        rc = self.proc.wait(timeout=60)
        self.log.close()
        return rc

    def log_text(self):
        with open(os.path.join(self.dir, "procamd.log"), encoding="utf-8", errors="replace") as f:
            return f.read()


def plain(args, tmp):
    d = Daemon(args.procamd, args.config, args.plugins, tmp, "plain")
    check(d.wait_ready(), "daemon ready")
    with Client(d.endpoint, timeout=20) as c:
        check(c.hello()["version"] == 1, "hello")
        check(c.ping()["uptime_s"] >= 0, "ping")
        names = [p["name"] for p in c.list_plugins()["plugins"]]
        check("structured-light" in names, f"list_plugins: {names}")
        check(c.describe_rig()["projector"]["width"] > 0, "describe_rig")
        events = []
        summary = c.scan("structured-light", "gray", rig_options={"scene": "plane"},
                         label="py", on_event=events.append)
        check(summary["state"] == "done", f"scan done: {summary}")
        check(any(e["event"] == "progress" for e in events), "progress events")
        check(events and events[-1]["event"] == "state" and events[-1]["state"] == "done",
              "last event is the final state")
        out = os.path.join(tmp, "py-out")
        m = c.fetch_all(summary["scan_id"], out)
        for f in m["files"]:
            check(os.path.getsize(os.path.join(out, f["name"])) == f["size_bytes"], f["name"])
        check(os.path.exists(os.path.join(out, "manifest.json")), "manifest.json written")
        listed = c.list_scans(state="done", limit=5)
        check(listed["scans"] and listed["scans"][0]["scan_id"] == summary["scan_id"],
              f"list_scans: newest done scan first: {listed}")
        scenes = [v["name"] for v in c.list_rig_options()["scene"]["values"]]
        check("plane" in scenes and "tilted-box" in scenes, f"list_rig_options: {scenes}")
        # Errors are exceptions with the daemon's code.
        try:
            c.result("no-such-scan")
            check(False, "result of an unknown scan raised")
        except ProcamError as e:
            check(e.code == "not_found", f"not_found: {e}")
        try:
            c.cancel(summary["scan_id"])
            check(False, "cancel of a finished scan raised")
        except ProcamError as e:
            check(e.code == "failed_precondition", f"failed_precondition: {e}")
        # A retried scan request (same id, same content) runs once.
        rid = c.new_request_id()
        a = c.submit_scan("structured-light", "gray", rig_options={"scene": "plane"}, request_id=rid)
        b = c.submit_scan("structured-light", "gray", rig_options={"scene": "plane"}, request_id=rid)
        check(a["scan_id"] == b["scan_id"] and b.get("duplicate") is True, f"dedupe: {a} {b}")
        c.cancel(a["scan_id"])
        st = c.status()
        check("metrics" in st and st["metrics"]["scans_done"] >= 1, f"metrics: {st}")
    # The example script.
    env = dict(os.environ, PROCAM_ENDPOINT=d.endpoint)
    r = subprocess.run([sys.executable, "-B", os.path.join(ROOT, "clients/python/examples/scan_and_fetch.py"),
                        "--scene", "tilted-box", "--out", os.path.join(tmp, "example-out")],
                       env=env, capture_output=True, text=True, timeout=240)
    print(r.stdout, r.stderr)
    check(r.returncode == 0 and "files in" in r.stdout, "example script")
    check(d.stop() == 0, "clean stop")


def curve(args, tmp):
    spub, ssec = keypair()
    cpub, csec = keypair()
    opub, osec = keypair()
    kdir = os.path.join(tmp, "keys")
    os.makedirs(kdir)
    with open(os.path.join(kdir, "server.secret"), "w") as f:
        f.write(ssec + "\n")
    os.chmod(os.path.join(kdir, "server.secret"), 0o600)
    with open(os.path.join(kdir, "client.secret"), "w") as f:
        f.write("# ours\n" + csec + "\n")
    with open(os.path.join(kdir, "authorized_keys"), "w") as f:
        f.write(cpub + "\n")
    d = Daemon(args.procamd, args.config, args.plugins, tmp, "curve",
               {"curve": {"secret_key_file": os.path.join(kdir, "server.secret"),
                          "authorized_keys": os.path.join(kdir, "authorized_keys")}})
    good = {"server_key": spub, "client_key": os.path.join(kdir, "client.secret")}
    ready = d.wait_ready(**good)
    check(ready, "curve daemon ready for the allowlisted key")
    if not ready:
        print(d.log_text())
        d.stop()
        return
    with Client(d.endpoint, timeout=5, **good) as c:
        check(c.status()["metrics"]["curve"] is True, "curve on in metrics")
    for who, keys in (("unknown key", {"server_key": spub, "client_key": osec}),
                      ("no key", {}),
                      ("wrong server key", {"server_key": opub, "client_key": csec})):
        try:
            with Client(d.endpoint, timeout=1.0, **keys) as c:
                c.ping()
            check(False, f"{who} got an answer")
        except Timeout:
            pass
    check("refused CURVE client" in d.log_text(), "refusals logged")
    check(d.stop() == 0, "curve daemon clean stop")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--procamd", required=True)
    ap.add_argument("--plugins", required=True)
    ap.add_argument("--config", required=True)
    args = ap.parse_args()
    os.environ.pop("PROCAM_SERVER_KEY", None)
    os.environ.pop("PROCAM_CLIENT_KEY", None)
    tmp = tempfile.mkdtemp(prefix="procam-py-")
    try:
        plain(args, tmp)
        curve(args, tmp)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    if failures:
        print(f"{len(failures)} failure(s)")
        return 1
    print("ok: Python client end to end (plain and CURVE)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
