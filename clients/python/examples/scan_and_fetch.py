#!/usr/bin/python3
# SPDX-License-Identifier: MIT
# Example: scan a scene through procamd with the Python client and download
# the results.
#   PYTHONPATH=clients/python /usr/bin/python3 clients/python/examples/scan_and_fetch.py \
#       --scene tilted-box --out out/py-scan
# CURVE: add --server-key server.pub --client-key me.secret (or set
# PROCAM_SERVER_KEY / PROCAM_CLIENT_KEY).
import argparse
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
from procam_client import Client, ProcamError  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--endpoint", help="default $PROCAM_ENDPOINT or tcp://127.0.0.1:5560")
    ap.add_argument("--plugin", default="structured-light")
    ap.add_argument("--method", default="gray")
    ap.add_argument("--scene", default="plane", help="simulated rig scene")
    ap.add_argument("--out", required=True, help="folder for the results")
    ap.add_argument("--server-key")
    ap.add_argument("--client-key")
    args = ap.parse_args()
    try:
        with Client(args.endpoint, server_key=args.server_key, client_key=args.client_key) as c:
            d = c.status()
            print(f"{d['version']} on rig {d['rig']}, {d['state']}")

            def show(ev):
                if ev["event"] == "state":
                    print("  state", ev["state"])
                elif ev["event"] == "progress" and ev["done"] == ev["total"]:
                    print(f"  {ev['stage']} round {ev['round']}: {ev['done']}/{ev['total']}")

            summary = c.scan(args.plugin, args.method, rig_options={"scene": args.scene},
                             on_event=show)
            if summary["state"] != "done":
                print("scan failed:", summary["error"], file=sys.stderr)
                return 1
            manifest = c.fetch_all(summary["scan_id"], args.out)
            print(f"scan {summary['scan_id']}: {len(manifest['files'])} files in {args.out}")
            ev = manifest.get("evaluation", {})
            if "within_1col_fraction" in ev:
                print(f"  within 1 projector column: {100 * ev['within_1col_fraction']:.1f}% of lit pixels")
    except ProcamError as e:
        print("procam:", e, file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
