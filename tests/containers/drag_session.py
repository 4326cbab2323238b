"""The Python side of scripts/container-test.sh: a drag through the load balancer.

    drag_session.py start  ADDR CA STATE DATA   session on cactus, 20 moves, state → STATE
    drag_session.py resume ADDR CA STATE        the same session after its replica died:
                                                same id, version and pose, then 20 more moves
    drag_session.py check  ADDR CA STATE        after the cluster's restart: same version, pose

CA "-" is a plain connection.

STATE is a JSON file (name, tokens, version, last move) beside STATE.npy (the pose). Each
move is retried on UNAVAILABLE for up to 30 s (a replica's death) with its request id, so a
retried move is never applied twice. Prints one line per phase, and the longest gap between
two answered moves (the failover gap) in `resume`.
"""
import json
import sys
import time

import grpc
import numpy as np

import hdeform


def connect(addr, ca):
    if ca == "-":
        return hdeform.connect(addr, timeout=30)
    with open(ca, "rb") as f:
        creds = grpc.ssl_channel_credentials(root_certificates=f.read())
    return hdeform.connect(addr, credentials=creds, timeout=30)


def move(s, k):
    """Move k: the handle translated by k mm along x, so a pose tells its move."""
    deadline = time.monotonic() + 30
    while True:
        try:
            return s.update(translate=[0.001 * k, 0, 0])
        except hdeform.Error as e:
            if e.code != grpc.StatusCode.UNAVAILABLE or time.monotonic() > deadline:
                raise
            time.sleep(0.2)


def drag(s, first, count):
    gaps, last = [], time.monotonic()
    for k in range(first, first + count):
        move(s, k)
        now = time.monotonic()
        gaps.append(now - last)
        last = now
    return max(gaps)


def save(path, s, k):
    V, _ = s.mesh()
    np.save(path + ".npy", V)
    with open(path, "w") as f:
        json.dump({"name": s.name, "edit_token": s.edit_token or s.token,
                   "version": s.info.version, "move": k}, f)


def load(path):
    with open(path) as f:
        st = json.load(f)
    return st, np.load(path + ".npy")


def reopen(hd, state_path):
    st, V = load(state_path)
    s = hd.session(st["name"], st["edit_token"])
    V_now, _ = s.mesh()
    err = float(np.abs(V_now - V).max())
    if s.info.version != st["version"] or err > 1e-9:
        sys.exit(f"FAIL: {st['name']}: version {s.info.version} (expected {st['version']}), "
                 f"pose off by {err:.3g}")
    return s, st


def main():
    phase, addr, ca, state = sys.argv[1:5]
    with connect(addr, ca) as hd:
        if phase == "start":
            data = sys.argv[5]
            s = hd.open("cactus")
            s.keep()  # outlives this script
            sel = f"{data}/botsch-sorkine/cactus.sel"
            s.constrain(fixed=hdeform.sel_file(sel, hdeform.FIXED),
                        handles=[hdeform.sel_file(sel, hdeform.HANDLE)])
            drag(s, 1, 20)
            save(state, s, 20)
            print(f"start: {s.name} at version {s.info.version} after 20 moves")
        elif phase == "resume":
            t0 = time.monotonic()
            s, st = reopen(hd, state)
            move(s, st["move"] + 1)
            first = time.monotonic() - t0
            gap = max(first, drag(s, st["move"] + 2, 19))
            save(state, s, st["move"] + 20)
            if s.info.version != st["version"] + 20:
                sys.exit(f"FAIL: version {s.info.version} after 20 moves from {st['version']}")
            print(f"resume: {s.name} went on from version {st['version']} with the same pose; "
                  f"now version {s.info.version}; first move answered {first * 1000:.0f} ms "
                  f"after the kill, longest gap between moves {gap * 1000:.0f} ms")
        elif phase == "check":
            s, st = reopen(hd, state)
            print(f"check: {s.name} survived the restart at version {s.info.version} "
                  f"with the same pose")
        else:
            sys.exit(f"unknown phase {phase}")


if __name__ == "__main__":
    main()
