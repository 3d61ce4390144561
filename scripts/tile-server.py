#!/usr/bin/env python3
"""A local tile server for streaming benchmarks: serves a folder (an XYZ pyramid, a COG) over HTTP on 127.0.0.1,
waiting --latency-ms before each answer (a service across the internet), many requests at once. At exit (Ctrl-C or
SIGTERM) it prints the requests and bytes it served.

    python3 scripts/tile-server.py ../shared/data/seasons/saclay_w_delivered/leafon_xyz --port 8765 --latency-ms 100
"""
import argparse
import functools
import http.server
import signal
import sys
import threading
import time


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder")
    ap.add_argument("--port", type=int, default=8765)
    ap.add_argument("--latency-ms", type=float, default=0.0)
    args = ap.parse_args()
    stats = {"requests": 0, "bytes": 0}
    lock = threading.Lock()

    class Handler(http.server.SimpleHTTPRequestHandler):
        def send_head(self):
            time.sleep(args.latency_ms / 1000.0)
            return super().send_head()

        def copyfile(self, source, outputfile):
            data = source.read()
            outputfile.write(data)
            with lock:
                stats["requests"] += 1
                stats["bytes"] += len(data)

        def log_message(self, fmt, *a):
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", args.port),
                                             functools.partial(Handler, directory=args.folder))
    server.daemon_threads = True

    def stop(*_):
        threading.Thread(target=server.shutdown).start()

    signal.signal(signal.SIGTERM, stop)
    signal.signal(signal.SIGINT, stop)
    print(f"serving {args.folder} on http://127.0.0.1:{args.port} with {args.latency_ms:g} ms latency", flush=True)
    server.serve_forever()
    print(f"served {stats['requests']} files, {stats['bytes'] / 1e6:.2f} MB", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
