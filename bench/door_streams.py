#!/usr/bin/env python3
"""What held streams cost the HTTP door: N WatchSession streams through gRPC-Web, then the
server's threads and RSS (from /proc), and the latency of a ListMeshes call beside them.

    python3 bench/door_streams.py --server build/server/hdeform-server --streams 1000

Starts its own server (--no-state, --http-port 0, a generated operator token); stdlib only.
"""
import argparse, os, re, secrets, socket, struct, subprocess, sys, time


def frame(message: bytes) -> bytes:
    return b"\0" + struct.pack(">I", len(message)) + message


def field(number: int, payload: bytes) -> bytes:  # a length-delimited protobuf field (< 128 B)
    return bytes([number << 3 | 2, len(payload)]) + payload


def post(port, path, body, token, extra=b""):
    return (f"POST {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n"
            f"Authorization: Bearer {token}\r\nContent-Type: application/grpc-web+proto\r\n"
            f"Content-Length: {len(body)}\r\n").encode() + extra + b"\r\n" + body


def proc_status(pid):
    text = open(f"/proc/{pid}/status").read()
    threads = int(re.search(r"Threads:\s+(\d+)", text).group(1))
    rss_kib = int(re.search(r"VmRSS:\s+(\d+)", text).group(1))
    return threads, rss_kib / 1024


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--server", required=True)
    ap.add_argument("--streams", type=int, default=1000)
    ap.add_argument("--calls", type=int, default=200, help="ListMeshes calls timed beside them")
    ap.add_argument("--extra", default="", help="more server flags, one string")
    a = ap.parse_args()
    token = secrets.token_hex(32)
    env = dict(PATH=os.environ.get("PATH", ""), HDEFORM_ADMIN_TOKEN=token)
    srv = subprocess.Popen([a.server, "--no-state", "--port", "0", "--http-port", "0",
                            "--max-watchers", str(a.streams + 10), *a.extra.split()],
                           stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=env, text=True)
    try:
        port = None
        for line in srv.stdout:
            m = re.search(r"http on \S+:(\d+)", line)
            if m:
                port = int(m.group(1))
                break
        up = socket.create_connection(("127.0.0.1", port))
        up.sendall((f"POST /upload?library=cactus&session_id=doorbench HTTP/1.1\r\nHost: 127.0.0.1\r\n"
                    f"Authorization: Bearer {token}\r\nX-Hdeform-Upload: 1\r\nContent-Length: 0\r\n"
                    "Connection: close\r\n\r\n").encode())
        reply = b""
        while chunk := up.recv(65536):
            reply += chunk
        assert b" 200 " in reply.split(b"\r\n")[0], reply[:200]
        idle_threads, idle_rss = proc_status(srv.pid)
        watch = frame(field(1, b"sessions/doorbench"))
        socks = []
        t0 = time.monotonic()
        for _ in range(a.streams):
            s = socket.create_connection(("127.0.0.1", port))
            s.sendall(post(port, "/hdeform.v1.Deformation/WatchSession", watch, token))
            socks.append(s)
        for s in socks:  # the response header and the first event: the stream is open
            s.settimeout(30)
            got = s.recv(4096)
            assert got.startswith(b"HTTP/1.1 200"), got[:400]
        opened = time.monotonic() - t0
        time.sleep(1)
        threads, rss = proc_status(srv.pid)
        lat = []
        call = post(port, "/hdeform.v1.Deformation/ListMeshes", frame(b""), token)
        c = socket.create_connection(("127.0.0.1", port))
        for _ in range(a.calls):
            t = time.monotonic()
            c.sendall(call)
            buf = b""
            while not buf.endswith(b"0\r\n\r\n"):
                buf += c.recv(65536)
            lat.append((time.monotonic() - t) * 1000)
        lat.sort()
        print(f"streams {a.streams} open in {opened:.2f} s | threads {idle_threads} idle -> {threads} "
              f"with streams | RSS {idle_rss:.0f} -> {rss:.0f} MiB ({(rss - idle_rss) * 1024 / a.streams:.1f} KiB/stream) "
              f"| ListMeshes beside them p50 {lat[len(lat) // 2]:.2f} ms p99 {lat[int(len(lat) * 0.99)]:.2f} ms")
        for s in socks:
            s.close()
    finally:
        srv.terminate()
        srv.wait(10)


if __name__ == "__main__":
    sys.exit(main())
