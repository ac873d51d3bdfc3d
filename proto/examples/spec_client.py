#!/usr/bin/python3
# SPDX-License-Identifier: MIT
# Minimal procam protocol v1 client written only from proto/PROTOCOL.md.
#
# Needs Python 3 and pyzmq (Debian: apt-get install python3-zmq; run with
# /usr/bin/python3). Usage:
#
#   spec_client.py --endpoint tcp://127.0.0.1:5560 list
#   spec_client.py --endpoint E scan --plugin P --method M [--param k=v ...]
#                  [--rig-option k=v ...] [--label TEXT] --out DIR
#
# `scan` sends hello, queues a scan with events over a DEALER socket (PROTOCOL.md
# 1.4), prints progress, waits for the final state (polling `status` when no
# event arrives, because events are advisory: PROTOCOL.md 6), asks for the
# result, and fetches every file of the manifest into DIR, plus the manifest
# itself as DIR/manifest.json. Values of k=v are JSON when they parse as JSON
# (10, 2.5, true, "x", [1,2]) and strings otherwise.
#
# Exit status: 0 scan done (or list printed); 1 the daemon answered with an
# error, or the scan failed; 2 bad command line; 3 no reply in time / broken
# message.
import argparse
import json
import os
import sys
import time

import zmq

PROTOCOL_VERSION = 1                       # PROTOCOL.md 4
FINAL_STATES = ("done", "failed")          # PROTOCOL.md 7
CLIENT_NAME = "spec_client/1.0"


class DaemonError(Exception):
    """An error reply (PROTOCOL.md 3.2): carries the error object."""

    def __init__(self, error):
        self.error = error
        text = f"{error.get('code')}: {error.get('message')}"
        if error.get("hint"):
            text += f" (hint: {error['hint']})"
        super().__init__(text)


class TransportError(Exception):
    """No reply in time, or a message that is not what PROTOCOL.md describes."""


def is_plain_file_name(name):
    """PROTOCOL.md 12 (fetch.file): never write outside the output folder."""
    return (isinstance(name, str) and 0 < len(name.encode()) <= 255 and not name.startswith(".")
            and ".." not in name and "/" not in name and "\\" not in name
            and all(ord(c) >= 0x20 and ord(c) != 0x7F for c in name))


def parse_assignment(text):
    """'k=v' -> (k, v) with v decoded as JSON when it is JSON, else the string."""
    if "=" not in text:
        raise argparse.ArgumentTypeError(f"expected key=value, got {text!r}")
    key, value = text.split("=", 1)
    try:
        return key, json.loads(value)
    except ValueError:
        return key, value


class Client:
    """One DEALER connection. Requests get ids "1", "2", ...; replies are matched
    by id; events that arrive meanwhile are queued for wait_event()."""

    def __init__(self, endpoint, reply_timeout_s):
        self.sock = zmq.Context.instance().socket(zmq.DEALER)
        self.sock.setsockopt(zmq.LINGER, 0)
        self.sock.connect(endpoint)
        self.reply_timeout_s = reply_timeout_s
        self.last_id = 0
        self.events = []

    def close(self):
        self.sock.close(0)

    def _recv(self, timeout_s):
        """Next message as (json body, raw data frame or None); None on timeout."""
        if not self.sock.poll(max(0, int(timeout_s * 1000))):
            return None
        frames = self.sock.recv_multipart()
        # DEALER sees [empty, json] or, for fetch, [empty, json header, data] (PROTOCOL.md 1.2).
        if len(frames) not in (2, 3) or frames[0] != b"":
            raise TransportError(f"unexpected framing: {len(frames)} frames")
        try:
            body = json.loads(frames[1].decode("utf-8"))
        except (UnicodeDecodeError, ValueError) as e:
            raise TransportError(f"message is not UTF-8 JSON: {e}")
        if not isinstance(body, dict) or body.get("procam") != PROTOCOL_VERSION:
            raise TransportError(f"not a protocol v{PROTOCOL_VERSION} message: {body!r:.200}")
        return body, (frames[2] if len(frames) == 3 else None)

    def request(self, type_, **fields):
        """Send one request; return (reply body, data frame). Raises DaemonError."""
        self.last_id += 1
        rid = str(self.last_id)
        msg = {"procam": PROTOCOL_VERSION, "id": rid, "type": type_, **fields}
        self.sock.send_multipart([b"", json.dumps(msg).encode("utf-8")])
        deadline = time.monotonic() + self.reply_timeout_s
        while True:
            got = self._recv(deadline - time.monotonic())
            if got is None:
                raise TransportError(f"no reply to {type_} within {self.reply_timeout_s} s")
            body, data = got
            if body.get("type") == "event":
                self.events.append(body)
                continue
            if body.get("id") is None and body.get("type") == "error":
                raise DaemonError(body.get("error", {}))  # the daemon could not read our id
            if body.get("id") != rid:
                continue  # a late reply to an earlier request: not ours
            if body.get("ok") is not True:
                raise DaemonError(body.get("error", {}))
            if body.get("type") != type_:
                raise TransportError(f"reply type {body.get('type')!r} to a {type_} request")
            return body, data

    def wait_event(self, timeout_s):
        """Next event, or None if none arrives within timeout_s."""
        if self.events:
            return self.events.pop(0)
        deadline = time.monotonic() + timeout_s
        while True:
            got = self._recv(deadline - time.monotonic())
            if got is None:
                return None
            if got[0].get("type") == "event":
                return got[0]
            # a reply nobody waits for (late reply after a timeout): ignore


def print_error(prefix, error):
    line = f"{prefix}: {error.get('code')}: {error.get('message')}"
    if error.get("hint"):
        line += f" (hint: {error['hint']})"
    print(line, file=sys.stderr)


def cmd_list(client, _args):
    hello, _ = client.request("hello", versions=[PROTOCOL_VERSION], client=CLIENT_NAME)
    print(f"{hello['daemon']} (protocol {hello['version']}), rig {hello['rig']}")
    reply, _ = client.request("list_plugins")
    for plugin in reply["plugins"]:
        print(f"{plugin['name']} {plugin['version']} ({plugin['file']})")
        for method in plugin["methods"]:
            print(f"  {method['name']}: {method['description']}")
            for p in method["params"]:
                extra = "".join(f" {k}={p[k]}" for k in ("min", "max", "choices", "unit") if k in p)
                print(f"    {p['name']} ({p['type']}, default {json.dumps(p['default'])}{extra}): "
                      f"{p['description']}")
    for rejected in reply["rejected"]:
        print_error(f"rejected {rejected['file']}", rejected["error"])
    return 0


def show_event(event):
    kind = event.get("event")
    if kind == "progress":
        line = f"{event['stage']} round {event['round']}: {event['done']}/{event['total']}"
        if event.get("message"):
            line += f" {event['message']}"
        print(line, flush=True)
    elif kind == "state":
        print(f"state: {event['state']}", flush=True)
    elif kind == "log":
        print(f"[{event['level']}] {event['message']}", flush=True)
    # unknown event kinds are ignored (PROTOCOL.md 4)


def wait_for_scan(client, scan_id, poll_s, timeout_s):
    """Follow events until the final state event; poll status when events stop.
    Returns the final state."""
    deadline = time.monotonic() + timeout_s
    expected_seq = 0
    while time.monotonic() < deadline:
        event = client.wait_event(min(poll_s, max(0.0, deadline - time.monotonic())))
        if event is None:
            # Events are advisory: ask the authoritative status (PROTOCOL.md 6).
            reply, _ = client.request("status", scan_id=scan_id)
            state = reply["scan"]["state"]
            if state in FINAL_STATES:
                print(f"state: {state} (from status)", flush=True)
                return state
            continue
        if event.get("scan_id") != scan_id:
            continue
        if event["seq"] != expected_seq:
            print(f"(missed events {expected_seq}..{event['seq'] - 1})", flush=True)
        expected_seq = event["seq"] + 1
        show_event(event)
        if event.get("event") == "state" and event.get("state") in FINAL_STATES:
            return event["state"]
    raise TransportError(f"scan {scan_id} did not finish within {timeout_s} s")


def fetch_file(client, scan_id, name, expected_size, out_dir, chunk):
    """Download one file in chunks (PROTOCOL.md 5.7) to out_dir/name."""
    if not is_plain_file_name(name):
        raise TransportError(f"manifest lists an unsafe file name {name!r}")
    path = os.path.join(out_dir, name)
    offset = 0
    with open(path + ".part", "wb") as out:
        while True:
            header, data = client.request("fetch", scan_id=scan_id, file=name, offset=offset,
                                          max_bytes=chunk)
            if data is None or len(data) != header["bytes"] or header["offset"] != offset:
                raise TransportError(f"fetch of {name} at {offset}: header and data disagree")
            out.write(data)
            offset += header["bytes"]
            if header["eof"]:
                break
            if header["bytes"] == 0:
                raise TransportError(f"fetch of {name} at {offset}: no data but not eof")
    if offset != header["size"] or (expected_size is not None and offset != expected_size):
        raise TransportError(f"{name}: got {offset} bytes, expected {expected_size}")
    os.replace(path + ".part", path)
    return offset


def cmd_scan(client, args):
    hello, _ = client.request("hello", versions=[PROTOCOL_VERSION], client=CLIENT_NAME)
    if "events" not in hello["capabilities"] or "fetch" not in hello["capabilities"]:
        print("daemon lacks the events/fetch capabilities", file=sys.stderr)
        return 1
    fields = {"plugin": args.plugin, "method": args.method, "events": True,
              "params": dict(args.param), "rig_options": dict(args.rig_option)}
    if args.label:
        fields["label"] = args.label
    reply, _ = client.request("scan", **fields)
    scan_id = reply["scan_id"]
    print(f"scan {scan_id}: {reply['state']}, {reply['queue_position']} ahead", flush=True)

    state = wait_for_scan(client, scan_id, args.poll_interval, args.scan_timeout)

    result, _ = client.request("result", scan_id=scan_id)
    manifest = result["manifest"]
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "manifest.json"), "w", encoding="utf-8") as f:
        json.dump(manifest, f, indent=2)
        f.write("\n")
    total = 0
    for entry in manifest.get("files", []):
        total += fetch_file(client, scan_id, entry["name"], entry.get("size_bytes"), args.out,
                            args.chunk)
        print(f"fetched {entry['name']} ({entry.get('size_bytes')} bytes)", flush=True)
    print(f"{len(manifest.get('files', []))} files, {total} bytes in {args.out}")
    for output in manifest.get("outputs", []):
        if output.get("kind") == "scalar":
            print(f"{output['name']} = {output.get('value')} {output.get('unit', '')}".rstrip())
    if state != "done" or result["state"] != "done":
        print_error(f"scan {scan_id} failed", manifest.get("error") or {})
        return 1
    return 0


def cmd_cancel(client, args):
    """PROTOCOL.md 5.8."""
    reply, _ = client.request("cancel", scan_id=args.scan_id)
    print(f"scan {reply['scan_id']}: was {reply['previous_state']}, now {reply['state']}")
    return 0


def cmd_ping(client, _args):
    """PROTOCOL.md 5.9: liveness, answered at once even while a scan runs."""
    reply, _ = client.request("ping")
    print(f"alive: up {reply['uptime_s']:.0f} s, daemon clock {reply['time_utc']}")
    return 0


def main(argv=None):
    ap = argparse.ArgumentParser(description="procam protocol v1 reference client")
    ap.add_argument("--endpoint", default="tcp://127.0.0.1:5560")
    ap.add_argument("--timeout", type=float, default=30.0, help="seconds to wait for a reply")
    sub = ap.add_subparsers(dest="command", required=True)
    sub.add_parser("list", help="list plugins and methods")
    sc = sub.add_parser("scan", help="run a scan and fetch its files")
    sc.add_argument("--plugin", required=True)
    sc.add_argument("--method", required=True)
    sc.add_argument("--param", type=parse_assignment, action="append", default=[],
                    metavar="K=V", help="method parameter (repeatable)")
    sc.add_argument("--rig-option", type=parse_assignment, action="append", default=[],
                    metavar="K=V", help="rig option, e.g. scene=tilted-box (repeatable)")
    sc.add_argument("--label", default="")
    sc.add_argument("--out", required=True, help="folder for the fetched files")
    sc.add_argument("--chunk", type=int, default=1 << 20, help="fetch max_bytes (1..8 MiB)")
    sc.add_argument("--poll-interval", type=float, default=5.0,
                    help="poll status after this many seconds without events")
    sc.add_argument("--scan-timeout", type=float, default=3600.0)
    cc = sub.add_parser("cancel", help="cancel a queued or running scan")
    cc.add_argument("scan_id")
    sub.add_parser("ping", help="is the daemon alive?")
    args = ap.parse_args(argv)

    client = Client(args.endpoint, args.timeout)
    try:
        commands = {"list": cmd_list, "scan": cmd_scan, "cancel": cmd_cancel, "ping": cmd_ping}
        return commands[args.command](client, args)
    except DaemonError as e:
        print_error("error", e.error)
        return 1
    except TransportError as e:
        print(f"error: {e}", file=sys.stderr)
        return 3
    except (KeyError, TypeError) as e:
        print(f"error: reply lacks a field PROTOCOL.md requires: {e!r}", file=sys.stderr)
        return 3
    finally:
        client.close()


if __name__ == "__main__":
    sys.exit(main())
