#!/usr/bin/env python3
"""Writes the committed seed corpora of tests/fuzz/corpus/ (small valid and invalid files per
target). Re-run after changing it: python3 tests/fuzz/make_seeds.py. Regression inputs found
by fuzzing are added by hand as corpus/<target>/regress-*."""
import base64
import json
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))
TETRA_V = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
TETRA_F = [(0, 2, 1), (0, 1, 3), (1, 2, 3), (0, 3, 2)]


def put(target, name, data):
    d = os.path.join(HERE, "corpus", target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data.encode() if isinstance(data, str) else data)


def obj():
    v = "".join(f"v {x} {y} {z}\n" for x, y, z in TETRA_V)
    put("fuzz_obj", "tetra.obj", "# tetra\n" + v + "".join(f"f {a+1} {b+1} {c+1}\n" for a, b, c in TETRA_F))
    put("fuzz_obj", "quad-corners.obj",
        "o q\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\ns off\nf 1/1/1 2/1/1 3/1/1 4/1/1\nl 1 2\n")
    put("fuzz_obj", "relative.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n")
    put("fuzz_obj", "forward.obj", "f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n")
    put("fuzz_obj", "bad-corner.obj", "v 0 0 0\nf 1 x 2\n")
    put("fuzz_obj", "garbage.obj", "\x00\x01binary\xffgarbage\n")


def off():
    v = "".join(f"{x} {y} {z}\n" for x, y, z in TETRA_V)
    f = "".join(f"3 {a} {b} {c}\n" for a, b, c in TETRA_F)
    put("fuzz_off", "tetra.off", "OFF\n4 4 6\n" + v + f)
    put("fuzz_off", "coff-comments.off", "COFF # colours\n\n4 1 0\n" + v.replace("\n", " 1 0 0 1\n") + "4 0 1 2 3 255 0 0\n")
    put("fuzz_off", "short.off", "OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    put("fuzz_off", "huge-count.off", "OFF\n2000000000 1 0\n0 0 0\n")
    be = lambda fmt, *a: struct.pack(">" + fmt, *a)
    body = be("iii", 4, 4, 6) + b"".join(be("fff", *p) for p in TETRA_V)
    body += b"".join(be("iiiii", 3, a, b, c, 0) for a, b, c in TETRA_F)
    put("fuzz_off", "tetra-binary.off", b"OFF BINARY\n" + body)
    put("fuzz_off", "binary-colour.off", b"OFF BINARY\n" + be("iii", 3, 1, 0) +
        b"".join(be("fff", *p) for p in TETRA_V[:3]) + be("iiiii", 3, 0, 1, 2, 3) + be("fff", 1, 0, 0))
    put("fuzz_off", "binary-truncated.off", b"OFF BINARY\n" + body[:40])


def ply():
    head = ("ply\nformat {fmt} 1.0\ncomment seed\nelement vertex 4\nproperty float x\nproperty float y\n"
            "property float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n")
    v = "".join(f"{x} {y} {z}\n" for x, y, z in TETRA_V)
    f = "".join(f"3 {a} {b} {c}\n" for a, b, c in TETRA_F)
    put("fuzz_ply", "tetra-ascii.ply", head.format(fmt="ascii") + v + f)
    for fmt, e in (("binary_little_endian", "<"), ("binary_big_endian", ">")):
        data = b"".join(struct.pack(e + "fff", *p) for p in TETRA_V)
        data += b"".join(struct.pack(e + "Biii", 3, a, b, c) for a, b, c in TETRA_F)
        put("fuzz_ply", f"tetra-{fmt}.ply", head.format(fmt=fmt).encode() + data)
    # Issue 8's hang: an element without properties and a huge count (0 bytes per row).
    put("fuzz_ply", "zero-byte-rows.ply",
        "ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
        "property float z\nelement junk 4000000000\nend_header\n")
    put("fuzz_ply", "double-ushort.ply",
        "ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty double x\nproperty double y\n"
        "property double z\nproperty uchar red\nelement face 1\nproperty list ushort uint vertex_index\n"
        "end_header\n".encode() + b"".join(struct.pack(">dddB", x, y, z, 7) for x, y, z in TETRA_V[:3])
        + struct.pack(">HIII", 3, 0, 1, 2))


def stl():
    facets = []
    for a, b, c in TETRA_F:
        facets.append((TETRA_V[a], TETRA_V[b], TETRA_V[c]))
    binary = b"seed binary stl".ljust(80, b" ") + struct.pack("<I", len(facets))
    for t in facets:
        binary += struct.pack("<3f", 0, 0, 1) + b"".join(struct.pack("<3f", *p) for p in t) + b"\0\0"
    put("fuzz_stl", "tetra-binary.stl", binary)
    put("fuzz_stl", "truncated-binary.stl", binary[:120])
    ascii_ = "solid t\n"
    for t in facets:
        ascii_ += "facet normal 0 0 1\n outer loop\n" + "".join(f"  vertex {x} {y} {z}\n" for x, y, z in t)
        ascii_ += " endloop\nendfacet\n"
    put("fuzz_stl", "tetra-ascii.stl", ascii_ + "endsolid t\n")
    put("fuzz_stl", "truncated-ascii.stl", ascii_[: len(ascii_) // 2])
    put("fuzz_stl", "solid-binary-header.stl", b"solid but binary".ljust(80, b" ") + binary[80:])


def gltf_model(buf_uri, nbytes):
    return {
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": nbytes, **({"uri": buf_uri} if buf_uri else {})}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                        {"buffer": 0, "byteOffset": 48, "byteLength": 24}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 1]},
                      {"bufferView": 1, "componentType": 5123, "count": 12, "type": "SCALAR"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}], "scene": 0,
    }


def gltf():
    data = b"".join(struct.pack("<3f", *p) for p in TETRA_V)
    data += b"".join(struct.pack("<3H", *t) for t in TETRA_F)
    uri = "data:application/octet-stream;base64," + base64.b64encode(data).decode()
    m = gltf_model(uri, len(data))
    put("fuzz_gltf", "tetra.gltf", json.dumps(m))
    strip = json.loads(json.dumps(m))
    strip["meshes"][0]["primitives"][0]["mode"] = 5
    put("fuzz_gltf", "strip.gltf", json.dumps(strip))
    noidx = json.loads(json.dumps(m))
    del noidx["meshes"][0]["primitives"][0]["indices"]
    noidx["meshes"].append({"primitives": [{"attributes": {"POSITION": 0}, "mode": 1}]})
    put("fuzz_gltf", "no-indices-and-lines.gltf", json.dumps(noidx))
    bad = json.loads(json.dumps(m))
    bad["accessors"][1]["count"] = 4611686018427387905  # stride × (count − 1) wraps to 0
    put("fuzz_gltf", "count-overflow.gltf", json.dumps(bad))
    put("fuzz_gltf", "not-json.gltf", "{\"asset\": [")
    # GLB: 12-byte header, JSON chunk (padded with spaces), BIN chunk (padded with zeros).
    js = json.dumps(gltf_model(None, len(data))).encode()
    js += b" " * (-len(js) % 4)
    bin_ = data + b"\0" * (-len(data) % 4)
    glb = struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(js) + 8 + len(bin_))
    glb += struct.pack("<I4s", len(js), b"JSON") + js + struct.pack("<I4s", len(bin_), b"BIN\0") + bin_
    put("fuzz_glb", "tetra.glb", glb)
    put("fuzz_glb", "truncated.glb", glb[: len(glb) - 30])
    put("fuzz_glb", "bad-chunk-length.glb", glb[:12] + struct.pack("<I", 0xFFFFFFF0) + glb[16:])
    put("fuzz_glb", "header-only.glb", glb[:12])


def sel():
    def s(nv, text):
        return struct.pack("<H", nv) + text.encode()
    put("fuzz_sel", "four.sel", s(4, "# a\n# b\n0\n1\n2\n1\n"))
    put("fuzz_sel", "too-many.sel", s(2, "0\n0\n0\n"))
    put("fuzz_sel", "bad-label.sel", s(3, "0\n7\n1\n"))
    put("fuzz_sel", "crlf.sel", s(3, "#\r\n0\r\n2\r\n1\r\n"))


def def_():
    put("fuzz_def", "identity.def", "# handle\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n")
    put("fuzz_def", "rotation.def", "#\n0 -1 0 0.5\n1 0 0 +2\n0 0 1 -1e-3\n0 0 0 1\n")
    put("fuzz_def", "short.def", "1 0 0 0\n0 1 0\n")
    put("fuzz_def", "nan.def", "1 0 0 nan\n0 1 0 0\n0 0 1 0\n0 0 0 1\n")
    put("fuzz_def", "not-affine.def", "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 1 1\n")


def grpc_web():
    frame = lambda flag, payload: struct.pack(">BI", flag, len(payload)) + payload
    put("fuzz_grpc_web_frames", "one-message", frame(0, b"\x0a\x03abc"))
    put("fuzz_grpc_web_frames", "message-and-trailers", frame(0, b"\x08\x01") + frame(0x80, b"grpc-status: 0\r\n"))
    put("fuzz_grpc_web_frames", "empty-frames", frame(0, b"") * 4)
    put("fuzz_grpc_web_frames", "truncated", frame(0, b"abcdef")[:8])
    put("fuzz_grpc_web_frames", "compressed", frame(1, b"xx"))
    put("fuzz_grpc_web_frames", "huge-length", struct.pack(">BI", 0, 0xFFFFFFFF) + b"abc")
    put("fuzz_grpc_web_frames", "timeout-5S", "5S")
    put("fuzz_grpc_web_frames", "timeout-max", "99999999H")


def http_request():
    """A control byte (bits 0-5: split stride, 0 = all at once; bit 6: Host policy "*"; bit 7:
    the door's 1 MiB upload chunk instead of 13 bytes), then the bytes a client sent on one
    connection."""
    frame = lambda flag, payload: struct.pack(">BI", flag, len(payload)) + payload
    crlf = lambda *lines: ("\r\n".join(lines) + "\r\n\r\n").encode()
    seed = lambda name, control, data: put("fuzz_http_request", name, bytes([control]) + data)
    grpc_web = lambda host, extra, body: crlf(
        "POST /hdeform.v1.Deformation/ListMeshes HTTP/1.1", f"Host: {host}",
        "Content-Type: application/grpc-web+proto", "X-Grpc-Web: 1", *extra,
        f"Content-Length: {len(body)}") + body
    seed("grpc-web-list-meshes", 0x40, grpc_web("viewer.example:8080", ["grpc-timeout: 30S"], frame(0, b"")))
    seed("grpc-web-origin", 0x07, grpc_web("viewer.example", ["Origin: https://viewer.example:443"],
                                           frame(0, b"\x0a\x05cactus") + frame(0x80, b"grpc-status: 0\r\n")))
    seed("grpc-web-cross-site", 0x00, grpc_web("a.team.example", ["Origin: http://evil.example",
                                                                  "X-Forwarded-Host: a.team.example, b"], frame(0, b"")))
    off = b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
    chunks = b"".join(b"%x\r\n%s\r\n" % (len(off[i:i + 16]), off[i:i + 16]) for i in range(0, len(off), 16))
    seed("upload-chunked", 0x43, crlf("POST /upload?filename=tri.off HTTP/1.1", "Host: localhost:8080",
                                      "X-Hdeform-Upload: 1", "Transfer-Encoding: chunked") + chunks + b"0\r\n\r\n")
    seed("upload-session-id", 0x00, crlf("POST /upload HTTP/1.1", "Host: 127.0.0.1", "X-Session-Id: s1",
                                         f"Content-Length: {len(off)}") + off)
    seed("pipelined-gets", 0x01, crlf("GET / HTTP/1.1", "Host: localhost") +
         crlf("GET /index.html HTTP/1.1", "Host: LOCALHOST.") +
         crlf("HEAD /assets/app.js HTTP/1.1", "Host: viewer.example", "Connection: close"))
    seed("xchunked-and-length", 0x00, crlf("POST /upload HTTP/1.1", "Host: localhost", "X-Hdeform-Upload: 1",
                                           "Transfer-Encoding: xchunked", "Content-Length: 5") + b"0\r\n\r\n")
    seed("chunked-and-length", 0x40, crlf("POST /upload HTTP/1.1", "Host: localhost",
                                          "Transfer-Encoding: chunked", "Content-Length: 5") + b"0\r\n\r\n")
    seed("two-transfer-encodings", 0x05, crlf("POST /upload HTTP/1.1", "Host: localhost", "Transfer-Encoding: gzip",
                                              "Transfer-Encoding: chunked") + b"3\r\nabc\r\n0\r\n\r\n")
    seed("host-ipv6", 0x02, crlf("GET / HTTP/1.1", "Host: [::1]:8080") + crlf("GET / HTTP/1.1", "Host: [fe80::1%eth0]"))
    seed("host-rebound", 0x00, crlf("GET / HTTP/1.1", "Host: evil.example") +
         crlf("GET / HTTP/1.1", "Host: localhost", "Host: evil.example"))
    seed("host-list", 0x00, crlf("GET / HTTP/1.1", "Host: viewer.example, .team.example, *.b.example, *"))
    seed("http10-no-host", 0x00, crlf("GET / HTTP/1.0"))
    # Whole streams through the door: pipelined calls, chunked gRPC-Web bodies, refusals.
    call = lambda method, extra, body, chunked=False: crlf(
        f"POST /hdeform.v1.Deformation/{method} HTTP/1.1", "Host: localhost:8080",
        "Content-Type: application/grpc-web+proto", "X-Grpc-Web: 1", *extra,
        "Transfer-Encoding: chunked" if chunked else f"Content-Length: {len(body)}") + (
        b"".join(b"%x\r\n%s\r\n" % (len(body[i:i + 7]), body[i:i + 7]) for i in range(0, len(body), 7))
        + b"0\r\n\r\n" if chunked else body)
    two = frame(0, b"") + frame(0, b"\x0a\x01x")
    seed("unary-two-messages", 0x00, call("ListSessions", [], two) + crlf("GET /healthz HTTP/1.1", "Host: localhost"))
    seed("unary-mid-frame", 0x03, call("ListMeshes", [], frame(0, b"abcdef")[:8]) + call("ListMeshes", [], frame(0, b"")))
    seed("grpc-web-chunked-pipelined", 0x09,
         call("GetSession", ["grpc-timeout: 250m"], frame(0, b"\x0a\x0asessions/s1"), chunked=True) +
         call("NoSuchMethod", [], frame(0, b"")) +
         call("CreateSession", ["Authorization: Bearer t"], frame(0, b"\x0a\x02\x0a\x00") * 3, chunked=True) +
         call("ListMeshes", ["Connection: close"], frame(0, b"")))
    seed("grpc-web-text", 0x40, crlf("POST /hdeform.v1.Deformation/ListMeshes HTTP/1.1", "Host: any.example",
                                     "Content-Type: application/grpc-web-text", "Content-Length: 8") + b"AAAAAAA=" +
         call("ListMeshes", [], frame(0x80, b"grpc-status: 0\r\n") + frame(0, b"")))
    seed("grpc-web-get", 0x00, crlf("GET /hdeform.v1.Deformation/ListMeshes HTTP/1.1", "Host: localhost"))
    seed("upload-library-repair", 0x80, crlf("POST /upload?library=capsule&repair=1e-3 HTTP/1.1", "Host: [::1]",
                                             "X-Hdeform-Upload: 1", "Content-Length: 0") +
         crlf("POST /upload?filename=a%2Eoff&session_id=s%31 HTTP/1.1", "Host: localhost", "X-Session-Id: s1",
              "Transfer-Encoding: chunked") + chunks + b"0\r\n\r\n" +
         crlf("POST /upload?filename=x&repair=abc HTTP/1.1", "Host: localhost", "X-Hdeform-Upload: 1"))
    seed("percent-path", 0x00, crlf("POST /hdeform.v1.Deformation%2FListMeshes HTTP/1.1", "Host: localhost",
                                     "Content-Type: application/grpc-web", "Content-Length: 5") + frame(0, b"") +
         crlf("GET /%2e%2e/%00 HTTP/1.1", "Host: localhost"))


def pb_varint(v):
    out = b""
    while True:
        b = v & 0x7F
        v >>= 7
        out += bytes([b | (0x80 if v else 0)])
        if not v:
            return out


def pb_field(num, wire, payload):
    key = pb_varint(num << 3 | wire)
    if wire == 0:
        return key + pb_varint(payload)
    if wire == 2:
        return key + pb_varint(len(payload)) + payload
    return key + payload  # fixed 32/64: payload already packed


def frame_decode():
    """Mode byte, vertex and triangle counts (LE u32), then a hdeform.v1.Frame (mode 0); or
    mode 1 and a raw QUANTIZED vertex buffer that the target meshopt-encodes itself."""
    vec3 = lambda x, y, z: b"".join(pb_field(i + 1, 1, struct.pack("<d", c)) for i, c in enumerate((x, y, z)))
    box = pb_field(1, 2, vec3(-1, 0, 2)) + pb_field(2, 2, vec3(1, 4, 2))
    n, t = 4, 2
    verts = b"".join(struct.pack("<3H2b", 65535 * (i % 2), 20000 * i, 7, 127 - 40 * i, -30) for i in range(n))
    head = lambda mode: bytes([mode]) + struct.pack("<II", n, t)
    quant = (pb_field(11, 0, 1) + pb_field(12, 2, verts) + pb_field(13, 2, box)
             + pb_field(6, 2, struct.pack("<2H", 0, 65535)) + pb_field(14, 5, struct.pack("<f", 2.5)))
    put("fuzz_frame_decode", "quantized", head(0) + quant)
    put("fuzz_frame_decode", "meshopt-wrong-bytes", head(0) + pb_field(11, 0, 2) + pb_field(12, 2, verts))
    f32 = pb_field(4, 2, struct.pack("<12f", *range(12))) + pb_field(5, 2, struct.pack("<12f", *([0, 0, 1] * 4)))
    put("fuzz_frame_decode", "float32", head(0) + f32 + pb_field(6, 2, struct.pack("<2f", 0.5, 1)))
    put("fuzz_frame_decode", "superseded", head(0) + pb_field(15, 0, 1))
    # MESHOPT_DELTA (not meshopt bytes: the fuzzer finds its way from here to the codec).
    put("fuzz_frame_decode", "meshopt-delta-key", head(0) + pb_field(11, 0, 3) + pb_field(12, 2, verts) + pb_field(13, 2, box))
    put("fuzz_frame_decode", "meshopt-delta", head(0) + pb_field(11, 0, 3) + pb_field(12, 2, verts) + pb_field(13, 2, box)
        + pb_field(18, 0, 1))
    put("fuzz_frame_decode", "roundtrip", bytes([1]) + verts * 40)


def stored_orderings():
    """hdeform.state.StoredOrderings of the target's mesh (hash 'a' * 64, 8 vertices): both
    orders, one only, and a near miss (a vertex twice), for fuzz_session_record."""
    packed = lambda p: b"".join(pb_varint(v) for v in p)
    head = pb_field(1, 2, b"a" * 64) + pb_field(2, 0, 8)
    put("fuzz_session_record", "orderings-both",
        head + pb_field(3, 2, packed([3, 1, 4, 0, 5, 7, 2, 6])) + pb_field(4, 2, packed(range(8))))
    put("fuzz_session_record", "orderings-one", head + pb_field(3, 2, packed(range(7, -1, -1))))
    put("fuzz_session_record", "orderings-repeat", head + pb_field(4, 2, packed([0, 1, 2, 3, 4, 5, 6, 6])))


if __name__ == "__main__":
    obj(); off(); ply(); stl(); gltf(); sel(); def_(); grpc_web(); http_request(); frame_decode()
    stored_orderings()
