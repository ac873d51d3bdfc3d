#!/usr/bin/python3
# SPDX-License-Identifier: MIT
# Checks proto/PROTOCOL.md against proto/schemas/: every schema is valid draft
# 2020-12, every tagged JSON example validates (and every invalid-request
# example is rejected), every message type has an example, and the error codes
# agree between PROTOCOL.md, the schemas and procam::code_name.
# Run with the system python3 (needs Debian's python3-jsonschema).
import json
import pathlib
import re
import sys

from jsonschema import Draft202012Validator, RefResolver

PROTO = pathlib.Path(__file__).resolve().parent.parent
ROOT = PROTO.parent
SCHEMAS = PROTO / "schemas"
REQUEST_TYPES = ["hello", "list_plugins", "describe_rig", "scan", "status", "result", "fetch",
                 "cancel", "ping", "list_scans", "list_rig_options", "calibrate_geometry"]

failures = []


def fail(msg):
    failures.append(msg)
    print("FAIL:", msg)


def load_schemas():
    store, by_file = {}, {}
    for path in sorted(SCHEMAS.glob("*.schema.json")):
        schema = json.loads(path.read_text())
        Draft202012Validator.check_schema(schema)
        if schema.get("$id") != "https://procam.invalid/proto/1/" + path.name:
            fail(f"{path.name}: $id does not match its file name")
        store[schema["$id"]] = schema
        by_file[path.name] = schema
    return store, by_file


STORE, SCHEMA = load_schemas()


def validator(name):
    schema = SCHEMA[name]
    return Draft202012Validator(schema, resolver=RefResolver.from_schema(schema, store=STORE))


V = {k: validator(k + ".schema.json") for k in ("request", "reply", "event", "manifest", "rig")}


def errors(kind, doc):
    """Messages of every schema violation of `doc` as a `kind` message."""
    def fmt(v):
        return [f"{'/'.join(map(str, e.absolute_path)) or '<top>'}: {e.message}"
                for e in v.iter_errors(doc)]
    found = fmt(V[kind])
    if found and kind in ("request", "reply") and isinstance(doc, dict):
        # The any-type schema only says "not valid under any"; explain with the
        # schema of the message's own type.
        t = doc.get("type")
        name = "error.reply.schema.json" if t == "error" else f"{t}.{kind}.schema.json"
        if isinstance(t, str) and name in SCHEMA:
            found = fmt(validator(name)) or found
    return found


def blocks():
    text = (PROTO / "PROTOCOL.md").read_text()
    pattern = re.compile(r"^```json ([a-z-]+)(?: ([a-z_]+))?\n(.*?)^```", re.M | re.S)
    for m in pattern.finditer(text):
        line = text.count("\n", 0, m.start()) + 1
        yield m.group(1), m.group(2), m.group(3), line


def check_examples():
    seen = {"request": set(), "reply": set(), "event": set(), "manifest": 0, "rig": 0,
            "invalid-request": set()}
    for kind, arg, body, line in blocks():
        where = f"PROTOCOL.md:{line} ({kind})"
        try:
            doc = json.loads(body)
        except json.JSONDecodeError as e:
            fail(f"{where}: not JSON: {e}")
            continue
        if kind == "invalid-request":
            if not errors("request", doc):
                fail(f"{where}: the request schema accepts an example marked invalid")
            seen[kind].add(arg)
            continue
        if kind not in V:
            fail(f"{where}: unknown example tag '{kind}'")
            continue
        for e in errors(kind, doc):
            fail(f"{where}: {e}")
        if kind in ("request", "reply"):
            seen[kind].add(doc.get("type"))
        elif kind == "event":
            seen[kind].add(doc.get("event"))
        else:
            seen[kind] += 1
        if kind == "reply" and doc.get("type") == "result":
            for e in errors("manifest", doc["manifest"]):
                fail(f"{where}: manifest: {e}")
    for t in REQUEST_TYPES:
        if t not in seen["request"]:
            fail(f"no request example of type {t}")
        if t not in seen["reply"]:
            fail(f"no reply example of type {t}")
    if "error" not in seen["reply"]:
        fail("no error reply example")
    for e in ("progress", "state", "log"):
        if e not in seen["event"]:
            fail(f"no {e} event example")
    if not seen["manifest"] or not seen["rig"]:
        fail("no manifest or rig example")
    if not seen["invalid-request"]:
        fail("no invalid-request examples")


def check_schemas_reject():
    """The schemas are not vacuous: broken messages fail."""
    good_scan = {"procam": 1, "id": "1", "type": "scan", "plugin": "p", "method": "m"}
    cases = [
        ("request", {**good_scan, "procam": 2}),
        ("request", {**good_scan, "params": []}),
        ("request", {**good_scan, "plugin": "A"}),
        ("request", {**good_scan, "id": ""}),
        ("request", {**good_scan, "id": "x" * 129}),
        ("request", {**good_scan, "typo": 1}),
        ("request", {"procam": 1, "id": "1", "type": "fetch", "scan_id": "s", "file": "a/b"}),
        ("request", {"procam": 1, "id": "1", "type": "fetch", "scan_id": "s", "file": ".hidden"}),
        ("request", {"procam": 1, "id": "1", "type": "fetch", "scan_id": "s", "file": "f",
                     "max_bytes": 8388609}),
        ("request", {"procam": 1, "id": "1", "type": "fetch", "scan_id": "s", "file": "f",
                     "max_bytes": 0}),
        ("request", {"procam": 1, "id": "1", "type": "hello", "versions": []}),
        ("request", {"procam": 1, "id": "1", "type": "nope"}),
        ("reply", {"procam": 1, "id": "1", "type": "scan", "scan_id": "s", "state": "queued",
                   "queue_position": 0}),  # no ok
        ("reply", {"procam": 1, "id": None, "type": "error", "ok": False,
                   "error": {"code": "no_such_code", "message": "", "hint": ""}}),
        ("reply", {"procam": 1, "id": "1", "type": "status", "ok": True}),
        ("event", {"procam": 1, "type": "event", "scan_id": "s", "seq": 0, "event": "progress"}),
        ("event", {"procam": 1, "type": "event", "scan_id": "s", "seq": 0, "event": "state",
                   "state": "failed"}),
        ("event", {"procam": 1, "type": "event", "scan_id": "s", "seq": -1, "event": "log",
                   "level": "info", "message": ""}),
        ("rig", {"name": "r", "projector": {}, "cameras": [], "state": {}}),
    ]
    for kind, doc in cases:
        if not errors(kind, doc):
            fail(f"{kind} schema accepts a broken message: {json.dumps(doc)}")
    accepted = [
        ("request", good_scan),
        ("request", {"procam": 1, "id": "1", "type": "fetch", "scan_id": "s", "file": "a.b_c-1.exr"}),
        ("reply", {"procam": 1, "id": "1", "type": "scan", "ok": True, "scan_id": "s",
                   "state": "queued", "queue_position": 0, "future_field": [1]}),
        ("event", {"procam": 1, "type": "event", "scan_id": "s", "seq": 0, "event": "future_kind"}),
    ]
    for kind, doc in accepted:
        for e in errors(kind, doc):
            fail(f"{kind} schema rejects a valid message {json.dumps(doc)}: {e}")


def check_error_codes():
    text = (PROTO / "PROTOCOL.md").read_text()
    section = text.split("### 11.1 Codes", 1)[1].split("### 11.2", 1)[0]
    doc_codes = re.findall(r"^\| `([a-z_]+)` \|", section, re.M)
    schema_codes = SCHEMA["common.schema.json"]["$defs"]["error_code"]["enum"]
    status_cpp = (ROOT / "hw/core/src/status.cpp").read_text()
    cpp_codes = [c for c in re.findall(r'return "([a-z_]+)";', status_cpp) if c != "ok"]
    if sorted(doc_codes) != sorted(schema_codes):
        fail(f"error codes differ: PROTOCOL.md {doc_codes} vs schema {schema_codes}")
    if sorted(set(cpp_codes)) != sorted(schema_codes):
        fail(f"error codes differ: procam::code_name {sorted(set(cpp_codes))} vs schema {schema_codes}")


if __name__ == "__main__":
    print("schemas:", len(SCHEMA), "examples:", sum(1 for _ in blocks()))
    check_examples()
    check_schemas_reject()
    check_error_codes()
    if failures:
        print(f"{len(failures)} failure(s)")
        sys.exit(1)
    print("ok: PROTOCOL.md examples, schemas and error codes agree")
