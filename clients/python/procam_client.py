# SPDX-License-Identifier: MIT
"""procam_client: a small Python client for procamd (proto/PROTOCOL.md).

Needs only Debian's python3-zmq (pyzmq). One module, no package to install:
put clients/python on PYTHONPATH (or copy this file).

    from procam_client import Client, ProcamError

    with Client("tcp://127.0.0.1:5560") as c:
        print(c.ping())                                   # {'uptime_s': ..., 'time_utc': ...}
        for p in c.list_plugins()["plugins"]:
            print(p["name"], [m["name"] for m in p["methods"]])
        summary = c.scan("structured-light", "gray", rig_options={"scene": "plane"},
                         on_event=lambda ev: print(ev["event"], ev.get("state", "")))
        manifest = c.fetch_all(summary["scan_id"], "out/")

API (every method raises ProcamError on an error reply, Timeout when the
daemon does not answer in time):

- Client(endpoint=None, timeout=10.0, server_key=None, client_key=None)
  endpoint: default $PROCAM_ENDPOINT or tcp://127.0.0.1:5560. For a daemon
  with CURVE (README "Remote access with CURVE keys"): server_key = the
  daemon's public key, client_key = our secret key; each either the 40-char
  Z85 text or the path of a file from `procam keygen`. Defaults:
  $PROCAM_SERVER_KEY / $PROCAM_CLIENT_KEY.
- call(type, request_id=None, **fields) -> dict   any request; returns the reply
  fields (without procam/id/type/ok).
- hello(), list_plugins(), describe_rig(), ping(), status(scan_id=None),
  result(scan_id) -> dict; cancel(scan_id) -> dict.
- submit_scan(plugin, method, params=None, rig_options=None, label="",
  events=False, request_id=None, save_frames=False, inputs=None) -> dict   queue a scan
  ({"scan_id", "state", "queue_position"}); retried with the same request id
  on a timeout, which the daemon answers with the same scan (never runs it
  twice). save_frames=True keeps the raw frames (frame-r<round>-<i>.png) in
  the scan's files for offline decoding. inputs={"depth_mm": (scan_id,
  "depth_mm")} feeds outputs of finished scans to a method that declares
  inputs (list_plugins; PROTOCOL.md 5.4): name -> (scan_id, output name), or
  name -> scan_id for an output of the same name.
- scan(plugin, method, ..., on_event=None, limit=1800.0) -> dict   queue, wait
  for the end (events, confirmed by polling status), return the final scan
  summary.
- fetch(scan_id, name, dest, chunk=4 MiB) -> int   download one file (atomic:
  written to dest.part, renamed); returns its size.
- fetch_all(scan_id, out_dir) -> dict   manifest.json plus every listed file.
- close() (or use `with`).

Threads: a Client holds one ZeroMQ socket; use one Client per thread.
"""

import json
import os
import random
import time

import zmq

__all__ = ["Client", "ProcamError", "Timeout", "load_key", "keypair", "DEFAULT_ENDPOINT"]

DEFAULT_ENDPOINT = "tcp://127.0.0.1:5560"
PROTOCOL = 1


class ProcamError(Exception):
    """An error reply from procamd (PROTOCOL.md section 11)."""

    def __init__(self, code, message, hint=""):
        super().__init__(f"{code}: {message}" + (f" ({hint})" if hint else ""))
        self.code, self.message, self.hint = code, message, hint


class Timeout(ProcamError):
    """No reply in time: the daemon is down, wedged, or refuses our CURVE key."""

    def __init__(self, message):
        super().__init__("unavailable", message,
                         "is procamd running? with CURVE: are our key and its key right?")


def load_key(value):
    """A Z85 CURVE key: `value` itself (40 characters) or the first
    non-comment line of the file it names."""
    if value is None:
        return None
    if isinstance(value, bytes):
        value = value.decode()
    if len(value) != 40 or os.path.isfile(value):  # Z85 may contain '/': a file only if one exists
        with open(value, encoding="utf-8") as f:
            lines = [ln.strip() for ln in f if ln.strip() and not ln.strip().startswith("#")]
        if not lines:
            raise ValueError(f"{value}: no key in file")
        value = lines[0]
    if len(value) != 40:
        raise ValueError("a Z85 CURVE key has 40 characters")
    return value


def keypair():
    """A new CURVE key pair (public, secret) as Z85 text."""
    pub, sec = zmq.curve_keypair()
    return pub.decode(), sec.decode()


def _safe_name(name):
    """PROTOCOL.md 12 (fetch.file): never write outside the output folder."""
    return (isinstance(name, str) and 0 < len(name.encode()) <= 255 and not name.startswith(".")
            and ".." not in name and "/" not in name and "\\" not in name
            and all(ord(ch) >= 0x20 and ord(ch) != 0x7F for ch in name))


class Client:
    def __init__(self, endpoint=None, timeout=10.0, server_key=None, client_key=None):
        self.endpoint = endpoint or os.environ.get("PROCAM_ENDPOINT") or DEFAULT_ENDPOINT
        self.timeout = float(timeout)
        self._server_key = load_key(server_key or os.environ.get("PROCAM_SERVER_KEY") or None)
        self._client_key = load_key(client_key or os.environ.get("PROCAM_CLIENT_KEY") or None)
        if self._server_key and not self._client_key:
            raise ValueError("a CURVE server key needs our secret key too (client_key)")
        self._prefix = "%016x" % random.SystemRandom().getrandbits(64)
        self._counter = 0
        self._ctx = zmq.Context.instance()
        self._sock = None
        self._events = []  # events received while waiting for a reply
        self._open()

    # -- socket ---------------------------------------------------------------
    def _open(self):
        if self._sock is not None:
            self._sock.close(linger=0)
        s = self._ctx.socket(zmq.DEALER)
        s.setsockopt(zmq.LINGER, 0)
        s.setsockopt(zmq.HEARTBEAT_IVL, 2000)
        s.setsockopt(zmq.HEARTBEAT_TIMEOUT, 6000)
        if self._server_key:
            pub = zmq.curve_public(self._client_key.encode())
            s.curve_serverkey = self._server_key.encode()
            s.curve_publickey = pub
            s.curve_secretkey = self._client_key.encode()
        s.connect(self.endpoint)
        self._sock = s

    def close(self):
        if self._sock is not None:
            self._sock.close(linger=0)
            self._sock = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def new_request_id(self):
        self._counter += 1
        return f"{self._prefix}-{self._counter}"

    # -- requests -------------------------------------------------------------
    def _roundtrip(self, request, timeout):
        self._sock.send_multipart([b"", json.dumps(request).encode()])
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0 or not self._sock.poll(int(left * 1000) + 1):
                if time.monotonic() >= deadline:
                    # The socket may hold a late reply: start afresh.
                    self._open()
                    raise Timeout(f"no reply from procamd at {self.endpoint} within {timeout:.1f} s")
                continue
            frames = self._sock.recv_multipart()
            i = 0
            while i < len(frames) and not frames[i]:
                i += 1
            if i >= len(frames):
                continue
            msg = json.loads(frames[i])
            if msg.get("type") == "event":
                self._events.append(msg)
                continue
            if msg.get("id") not in (request["id"], None):
                continue  # a late reply to an earlier request
            data = frames[i + 1] if i + 1 < len(frames) else None
            return msg, data

    def _request(self, type_, fields, request_id=None, retries=0, timeout=None):
        req = {"procam": PROTOCOL, "id": request_id or self.new_request_id(), "type": type_}
        req.update({k: v for k, v in fields.items() if v is not None})
        for attempt in range(retries + 1):
            try:
                msg, data = self._roundtrip(req, timeout or self.timeout)
                break
            except Timeout:
                if attempt == retries:
                    raise
        if not msg.get("ok"):
            e = msg.get("error") or {}
            raise ProcamError(e.get("code", "internal"), e.get("message", "error"), e.get("hint", ""))
        body = {k: v for k, v in msg.items() if k not in ("procam", "id", "type", "ok")}
        return body, data

    def call(self, type_, request_id=None, **fields):
        """Any request; idempotent ones are retried once after a timeout."""
        retries = 0 if type_ in ("scan", "cancel", "calibrate_geometry") and request_id is None else 1
        return self._request(type_, fields, request_id, retries)[0]

    def hello(self, client="procam_client.py/1"):
        return self.call("hello", versions=[PROTOCOL], client=client)

    def list_plugins(self):
        return self.call("list_plugins")

    def describe_rig(self):
        return self.call("describe_rig")["rig"]

    def ping(self):
        return self.call("ping")

    def list_scans(self, state=None, limit=None):
        """Scan summaries, newest first: {"scans", "total", "truncated"}."""
        return self.call("list_scans", state=state, limit=limit)

    def list_rig_options(self):
        """{"<option>": {"type", "description", "default", "values"}}; the sim rig lists its scenes."""
        return self.call("list_rig_options")["options"]

    def calibrate_geometry(self, scans, inner_corners=None, square_mm=None, label="", events=False, request_id=None,
                           board=None):
        """Queue a geometric calibration from finished pose scans (PROTOCOL.md 5.12).

        scans: ids of structured-light/gray scans with params rows=true and
        save_frames, one board pose each (3..50); inner_corners: (cols,
        rows); square_mm: edge of one square. Or board: the request's board
        object as is, e.g. a ChArUco board {"type": "charuco", "squares": [5, 7],
        "square_mm": 40, "marker_mm": 30, "dictionary": "DICT_5X5_100"}.
        Returns {"scan_id", "state", "queue_position"}; when the record is
        done, result(scan_id)["calibration"] holds the per-view table and
        "rig", and fetch its "result_file"."""
        if board is None:
            board = {"inner_corners": list(inner_corners), "square_mm": square_mm}
        fields = {"scans": list(scans), "board": board}
        if label:
            fields["label"] = label
        if events:
            fields["events"] = True
        return self.call("calibrate_geometry", request_id=request_id, **fields)

    def status(self, scan_id=None):
        r = self.call("status", scan_id=scan_id)
        return r["scan"] if scan_id else r["daemon"]

    def result(self, scan_id):
        return self.call("result", scan_id=scan_id)["manifest"]

    def cancel(self, scan_id):
        return self.call("cancel", scan_id=scan_id)

    def submit_scan(self, plugin, method, params=None, rig_options=None, label="", events=False,
                    request_id=None, save_frames=False, inputs=None):
        wire_inputs = {}
        for name, src in (inputs or {}).items():
            scan_id, output = (src, name) if isinstance(src, str) else tuple(src)
            wire_inputs[name] = {"scan": scan_id, "output": output}
        fields = {"plugin": plugin, "method": method, "params": params or {},
                  "rig_options": rig_options or None, "label": label or None,
                  "events": True if events else None,
                  "save_frames": True if save_frames else None,
                  "inputs": wire_inputs or None}
        # Same id + same content: the daemon answers a retry with the same scan.
        return self._request("scan", fields, request_id or self.new_request_id(), retries=2)[0]

    def scan(self, plugin, method, params=None, rig_options=None, label="", on_event=None,
             limit=1800.0, save_frames=False, inputs=None):
        accepted = self.submit_scan(plugin, method, params, rig_options, label, events=True,
                                    save_frames=save_frames, inputs=inputs)
        scan_id = accepted["scan_id"]
        deadline = time.monotonic() + limit
        last_poll = time.monotonic()
        while time.monotonic() < deadline:
            ended = False
            for ev in self._take_events(scan_id):
                if on_event:
                    on_event(ev)
                ended |= ev.get("event") == "state" and ev.get("state") in ("done", "failed")
            if ended:
                return self.status(scan_id)
            if self._sock.poll(200):
                frames = self._sock.recv_multipart()
                body = [f for f in frames if f]
                if body:
                    msg = json.loads(body[0])
                    if msg.get("type") == "event":
                        self._events.append(msg)
                continue
            if time.monotonic() - last_poll > 1.0:  # events are advisory: confirm
                last_poll = time.monotonic()
                s = self.status(scan_id)
                if s["state"] in ("done", "failed"):
                    for ev in self._take_events(scan_id):
                        if on_event:
                            on_event(ev)
                    return s
        raise Timeout(f"scan {scan_id} did not finish within {limit:.0f} s")

    def _take_events(self, scan_id):
        mine = [e for e in self._events if e.get("scan_id") == scan_id]
        self._events = [e for e in self._events if e.get("scan_id") != scan_id]
        return mine

    def fetch(self, scan_id, name, dest, chunk=4 << 20):
        if not _safe_name(name):
            raise ValueError(f"unsafe file name {name!r}")
        part = dest + ".part"
        offset = 0
        with open(part, "wb") as f:
            while True:
                header, data = self._request("fetch", {"scan_id": scan_id, "file": name,
                                                       "offset": offset, "max_bytes": chunk},
                                             retries=1)
                data = data or b""
                if len(data) != header["bytes"]:
                    raise ProcamError("corrupt_data", f"fetch of {name}: header and data disagree")
                f.write(data)
                offset += len(data)
                if header["eof"] or not data:
                    break
        os.replace(part, dest)
        return offset

    def fetch_all(self, scan_id, out_dir):
        manifest = self.result(scan_id)
        os.makedirs(out_dir, exist_ok=True)
        tmp = os.path.join(out_dir, "manifest.json.part")
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump(manifest, f, indent=2)
        os.replace(tmp, os.path.join(out_dir, "manifest.json"))
        for entry in manifest.get("files", []):
            if _safe_name(entry.get("name")):
                size = self.fetch(scan_id, entry["name"], os.path.join(out_dir, entry["name"]))
                if entry.get("size_bytes") is not None and size != entry["size_bytes"]:
                    raise ProcamError("corrupt_data", f"{entry['name']}: got {size} bytes, "
                                                      f"manifest says {entry['size_bytes']}")
        return manifest
