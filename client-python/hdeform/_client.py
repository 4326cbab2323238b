"""connect(), Client and Session: the hdeform.v1.Deformation service with numpy in and out."""
import csv
import itertools
import os
import time
import uuid
import weakref
from dataclasses import dataclass

import grpc
import numpy as np

from ._errors import Error, from_rpc_error
from ._frames import Frame, Measures, decode, encoding_value
from ._meshio import parse_off, ply_bytes
from ._proto import pb, pb_grpc
from ._selectors import region
from ._server import LocalServer
from ._transforms import to_transform, Transform

CHUNK = 1 << 20  # upload chunks (gRPC's default limit is 4 MiB per message)
_UNITS = {"area": pb.BETA_UNITS_AREA, "raw": pb.BETA_UNITS_RAW}
_FORMATS = {"glb": pb.MESH_FORMAT_GLB, "obj": pb.MESH_FORMAT_OBJ, "off": pb.MESH_FORMAT_OFF,
            "ply": pb.MESH_FORMAT_PLY}
_GLB_COMPRESSION = {None: pb.GLB_COMPRESSION_NONE, "none": pb.GLB_COMPRESSION_NONE,
                    "quantized": pb.GLB_COMPRESSION_QUANTIZED,
                    "meshopt": pb.GLB_COMPRESSION_MESHOPT}


def _rpc(fn, *args, **kwargs):
    try:
        return fn(*args, **kwargs)
    except grpc.RpcError as e:
        raise from_rpc_error(e) from None


def _metadata(token, session=None):
    """Call metadata: the token, and for a call of a session its id as `x-session-id`, by
    which a load balancer sends every call of a session to the replica that holds it
    (docs/deployment.md "Session affinity")."""
    md = (("authorization", f"Bearer {token}"),) if token else ()
    if session:
        md += (("x-session-id", session.split("/", 1)[-1]),)
    return md


def _units(units):
    if units not in _UNITS:
        raise ValueError(f"units: 'area' or 'raw', got {units!r}")
    return _UNITS[units]


def _beta_proto(value, units="area", local=None):
    b = pb.Beta(units=_units(units))
    if isinstance(value, str):
        if value != "auto":
            raise ValueError(f"beta: a number in [0, 1) or 'auto', got {value!r}")
        b.automatic = True
    else:
        b.value = float(value)
    for entry in local or ():
        b.local.append(pb.LocalBeta(region=region(entry["region"]), beta=float(entry["beta"]),
                                    falloff_radius=float(entry.get("falloff_radius", 0.0))))
    return b


@dataclass
class LibraryMesh:
    name: str
    path: str
    has_benchmark: bool


@dataclass
class SweepRow:
    beta: float
    measures: Measures


class SweepResult(list):
    """Sweep rows (SweepRow) in request order."""

    columns = ["beta", "e", "e_iso_n", "e_conf_n", "e_area_pct", "max_e_iso", "max_e_conf",
               "max_ef2", "flips"]

    def records(self):
        """One dict per row: beta and the seven measures."""
        return [dict(beta=r.beta, **r.measures.as_dict()) for r in self]

    def to_dataframe(self):
        """A pandas DataFrame (needs pandas: apt-get install python3-pandas)."""
        import pandas  # noqa: PLC0415 - optional dependency
        return pandas.DataFrame.from_records(self.records(), columns=self.columns)

    def to_csv(self, path):
        with open(os.fspath(path), "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=self.columns)
            w.writeheader()
            w.writerows(self.records())


class Client:
    """A connection to an hdeform-server (make one with hdeform.connect()). As a context
    manager it deletes, on exit, the sessions it created (unless kept with Session.keep()) and
    stops its private server."""

    def __init__(self, address, token=None, credentials=None, server=None, ready_timeout=30.0):
        self.address = address
        self.token = token
        self.server = server
        options = [("grpc.max_receive_message_length", -1),
                   ("grpc.max_send_message_length", -1)]
        if credentials is not None:
            self.channel = grpc.secure_channel(address, credentials, options=options)
        else:
            self.channel = grpc.insecure_channel(address, options=options)
        self.stub = pb_grpc.DeformationStub(self.channel)
        self._created = weakref.WeakSet()
        if ready_timeout:
            try:
                grpc.channel_ready_future(self.channel).result(timeout=ready_timeout)
            except grpc.FutureTimeoutError:
                self.close()
                raise Error(f"no hdeform-server answers at {address} "
                            f"(waited {ready_timeout:g} s)",
                            grpc.StatusCode.UNAVAILABLE) from None

    # --- sessions -------------------------------------------------------------------------
    def meshes(self):
        """The server's mesh library."""
        r = _rpc(self.stub.ListMeshes, pb.ListMeshesRequest())
        return [LibraryMesh(m.name, m.path, m.has_benchmark) for m in r.meshes]

    def _create(self, header, data=b""):
        # The id is chosen here so that the creating call is routed by it, like every later
        # call of the session (docs/deployment.md).
        if not header.session_id:
            header.session_id = uuid.uuid4().hex[:24]
        def requests():
            yield pb.CreateSessionRequest(header=header)
            for i in range(0, len(data), CHUNK):
                yield pb.CreateSessionRequest(chunk=data[i:i + CHUNK])
        info = _rpc(self.stub.CreateSession, requests(),
                    metadata=_metadata(None, header.session_id))
        s = Session(self, info, info.edit_token, view_token=info.view_token, owned=True)
        self._created.add(s)
        return s

    def open(self, mesh, session_id=""):
        """A new session on a library mesh (a name from meshes(), e.g. "cactus")."""
        return self._create(pb.CreateSessionHeader(library_mesh=mesh, session_id=session_id))

    def upload(self, V, F, session_id="", filename="mesh.ply"):
        """A new session on the mesh (V n×3, F m×3), sent as a binary PLY of doubles: vertex
        ids and frame rows are V's rows."""
        data = ply_bytes(V, F)
        return self._create(pb.CreateSessionHeader(filename=filename, total_bytes=len(data),
                                                   session_id=session_id), data)

    def upload_file(self, path, session_id=""):
        """A new session on a mesh file (.obj .off .ply .stl .glb, or a self-contained .gltf)."""
        with open(os.fspath(path), "rb") as f:
            data = f.read()
        return self._create(pb.CreateSessionHeader(filename=os.path.basename(os.fspath(path)),
                                                   total_bytes=len(data),
                                                   session_id=session_id), data)

    def session(self, name, token=None):
        """Attach to an existing session ("sessions/ID" or "ID") with its edit or view token
        (default: the client's token, e.g. the operator token)."""
        token = token if token is not None else self.token
        info = _rpc(self.stub.GetSession, pb.GetSessionRequest(name=name),
                    metadata=_metadata(token, name))
        return Session(self, info, token, owned=False)

    def sessions(self):
        """Names of the sessions the client's token opens (all with the operator token)."""
        r = _rpc(self.stub.ListSessions, pb.ListSessionsRequest(),
                 metadata=_metadata(self.token))
        return [s.name for s in r.sessions]

    # --- lifetime -------------------------------------------------------------------------
    def close(self):
        """Close the channel and stop the private server (if any)."""
        self.channel.close()
        if self.server is not None:
            self.server.stop()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        try:
            for s in list(self._created):
                if not s._kept and not s.deleted:
                    try:
                        s.delete()
                    except Error:
                        pass
        finally:
            self.close()

    def __repr__(self):
        return f"hdeform.Client({self.address!r}{', private server' if self.server else ''})"


def connect(address=None, *, token=None, server=None, mesh_dir=None, state_dir=None,
            server_args=(), credentials=None, timeout=30.0):
    """A Client. With an address ("host:port"): that server, presenting `token` (an operator
    token, or a session token for Client.session()). Without: a private hdeform-server
    (`server`, else $HDEFORM_SERVER, PATH, the build tree) on a free loopback port, with a
    random operator token the client presents, stopped by close()/the context's exit/at exit.
    That server gets a clean environment (none of the caller's HDEFORM_* settings): configure
    it with `server_args`."""
    if address is not None:
        return Client(address, token=token, credentials=credentials, ready_timeout=timeout)
    srv = LocalServer(server, mesh_dir=mesh_dir, state_dir=state_dir, args=server_args,
                      timeout=timeout)
    try:
        return Client(srv.address, token=token or srv.admin_token, server=srv,
                      ready_timeout=timeout)
    except BaseException:
        srv.stop(keep_log=True)
        raise


class Session:
    """One server session. Keeps its tokens (`token` is the one it presents; `edit_token` /
    `view_token` when this client created it). As a context manager it deletes the session
    on exit if this client created it."""

    def __init__(self, client, info, token, view_token=None, owned=False):
        # Who this script is in the session's history and to other editors: its changes
        # carry it, and undo() / redo() act on its own steps.
        self.client_id = "py-" + uuid.uuid4().hex[:12]
        self.client = client
        self.info = info  # the latest hdeform.v1.Session
        self.name = info.name
        self.token = token
        self.edit_token = token if owned else None
        self.view_token = view_token
        self.owned = owned
        self.deleted = False
        self._kept = False
        self._sequence = itertools.count(1)

    def _call(self, method, request):
        # A change carries a request id, so one retry after UNAVAILABLE (the answer may have
        # been lost after the server applied it) is answered, never applied twice.
        retry = "request_id" in request.DESCRIPTOR.fields_by_name
        if retry and not request.request_id:
            request.request_id = uuid.uuid4().hex
        stub = getattr(self.client.stub, method)
        try:
            return _rpc(stub, request, metadata=_metadata(self.token, self.name))
        except Error as e:
            if not retry or e.code != grpc.StatusCode.UNAVAILABLE:
                raise
            time.sleep(0.5)
            return _rpc(stub, request, metadata=_metadata(self.token, self.name))

    # --- state ----------------------------------------------------------------------------
    @property
    def id(self):
        return self.name.split("/", 1)[-1]

    def refresh(self):
        """Re-read the session's state (self.info) from the server."""
        self.info = self._call("GetSession", pb.GetSessionRequest(name=self.name))
        return self

    vertex_count = property(lambda self: self.info.vertex_count)
    triangle_count = property(lambda self: self.info.triangle_count)
    version = property(lambda self: self.info.version)
    mesh_name = property(lambda self: self.info.mesh_name)

    @property
    def handle_count(self):
        return len(self.info.constraints.handles)

    @property
    def fixed(self):
        """The fixed vertices' engine ids (sorted)."""
        return np.asarray(self.info.constraints.fixed.ids, dtype=np.int64)

    @property
    def handles(self):
        """Each handle's engine vertex ids (sorted)."""
        return [np.asarray(h.ids, dtype=np.int64) for h in self.info.constraints.handles]

    @property
    def pivots(self):
        """Each handle's default pivot (rest centroid), k×3."""
        return np.array([[p.x, p.y, p.z] for p in self.info.pivots]).reshape(-1, 3)

    @property
    def bbox(self):
        """The rest bounding box, 2×3 (min, max)."""
        a, b = self.info.bbox_min, self.info.bbox_max
        return np.array([[a.x, a.y, a.z], [b.x, b.y, b.z]])

    # --- meshes ---------------------------------------------------------------------------
    def mesh_bytes(self, format="glb", rest=False, compression=None):  # noqa: A002 - the proto's name
        """The rest or current mesh as a file (glb, obj, off, ply). compression (GLB only):
        "quantized" (KHR_mesh_quantization) or "meshopt" (EXT_meshopt_compression), see
        docs/api.md "Compressed GLB"; hdeform does not read those back."""
        if format not in _FORMATS:
            raise ValueError(f"format: one of {sorted(_FORMATS)}, got {format!r}")
        if compression not in _GLB_COMPRESSION:
            raise ValueError(f"compression: None, 'quantized' or 'meshopt', got {compression!r}")
        req = pb.GetMeshRequest(name=self.name, rest=rest, format=_FORMATS[format],
                                glb_compression=_GLB_COMPRESSION[compression])
        try:
            return b"".join(c.data for c in self.client.stub.GetMesh(
                req, metadata=_metadata(self.token, self.name)))
        except grpc.RpcError as e:
            raise from_rpc_error(e) from None

    def mesh(self, rest=False):
        """(V float64 n×3, F int64 m×3) of the rest or current mesh, exact doubles, in engine
        vertex order (= Frame.V order except for glTF uploads)."""
        return parse_off(self.mesh_bytes("off", rest=rest))

    def rest(self):
        """mesh(rest=True)."""
        return self.mesh(rest=True)

    def save(self, path, rest=False, compression=None):
        """Write the current (or rest) mesh; the extension picks the format. compression: as
        mesh_bytes (a .glb only)."""
        ext = os.path.splitext(os.fspath(path))[1].lower().lstrip(".")
        data = self.mesh_bytes(ext, rest=rest, compression=compression)
        with open(os.fspath(path), "wb") as f:
            f.write(data)

    # --- editing --------------------------------------------------------------------------
    def constrain(self, fixed=None, handles=(), expected_version=0, discard_timeline=False):
        """Set the fixed region and the handle regions. A region: a selector (hdeform.ids,
        box, sphere, half_space, sel_file, …), a dict ({"box": (min, max)}), an id array, or
        a list of selectors (their union). Resets every handle transform to identity.
        New constraints drop the timeline's keys (undo() brings them back); keys another
        client set are dropped only with discard_timeline=True (else hdeform.Error ABORTED)."""
        c = pb.Constraints(handles=[region(h) for h in handles])
        if fixed is not None:
            c.fixed.CopyFrom(region(fixed))
        self.info = self._call("SetConstraints", pb.SetConstraintsRequest(
            name=self.name, constraints=c, expected_version=expected_version,
            client_id=self.client_id, discard_timeline=discard_timeline))
        return self

    @property
    def beta(self):
        """β's value (the pick when automatic; see beta_automatic, beta_units). Set a number
        (area units) or "auto"; set_beta() for raw units and local entries."""
        return self.info.beta.value

    @beta.setter
    def beta(self, value):
        self.set_beta(value)

    @property
    def beta_automatic(self):
        return self.info.beta.automatic

    @property
    def beta_units(self):
        return "raw" if self.info.beta.units == pb.BETA_UNITS_RAW else "area"

    def set_beta(self, value, units="area", local=None, expected_version=0):
        """β = value (0 ≤ β < 1, or "auto") in `units` ("area" or "raw"); `local`: a list of
        {"region": …, "beta": b, "falloff_radius": r}."""
        self.info = self._call("SetBeta", pb.SetBetaRequest(
            name=self.name, beta=_beta_proto(value, units, local),
            expected_version=expected_version, client_id=self.client_id))
        return self

    def _transforms(self, transforms, single):
        if transforms is not None:
            if any(v is not None for v in single.values()):
                raise TypeError("update: pass either transforms=[...] or rotate=/translate=/…")
            if isinstance(transforms, (Transform, dict)):
                transforms = [transforms]
            return [to_transform(t).to_proto() for t in transforms]
        t = Transform(**single)
        k = self.handle_count
        if k != 1 and any(v is not None for v in single.values()):
            raise TypeError(f"update: the session has {k} handles; pass transforms=[one per "
                            "handle] (hdeform.transform(...), dicts, 4×4 matrices or None)")
        return [t.to_proto()] * k

    def update(self, transforms=None, *, rotate=None, translate=None, scale=None, pivot=None,
               matrix=None, energies=False, encoding="float32", double=False, dragging=False,
               expected_version=0):
        """Move the handles and solve: a Frame. For one handle pass rotate= (quaternion
        w, x, y, z or 3×3), translate=, scale=, pivot=, matrix= (4×4); for several,
        transforms=[one per handle]. double=True also reads the result's exact doubles
        (GetMesh OFF) into frame.V instead of the float32 buffer (engine vertex order)."""
        ts = self._transforms(transforms, dict(rotate=rotate, translate=translate, scale=scale,
                                                pivot=pivot, matrix=matrix))
        seq = next(self._sequence)
        raw = self._call("UpdateHandles", pb.UpdateHandlesRequest(
            name=self.name, sequence=seq, transforms=ts, energies=energies, dragging=dragging,
            expected_version=expected_version, client_id=self.client_id,
            format=pb.FrameFormat(encoding=encoding_value(encoding))))
        frame = decode(raw)
        self.info.version = raw.version
        if double:
            frame.V = self.mesh()[0]
        return frame

    def sweep(self, betas, units="area", transforms=None):
        """Measures for each β (the session is not changed) at the current transforms or at
        `transforms` (one per handle): a SweepResult (list of SweepRow; .to_dataframe())."""
        req = pb.SweepRequest(name=self.name, betas=[float(b) for b in betas],
                              units=_units(units))
        if transforms is not None:
            req.transforms.extend(self._transforms(transforms, {}))
        r = self._call("Sweep", req)
        return SweepResult(SweepRow(row.beta, Measures.from_proto(row.measures))
                           for row in r.rows)

    # --- history and snapshots (docs/api.md "History and snapshots") --------------------
    def undo(self, step=0, discard_timeline=False):
        """Revert this script's latest change (or history step `step`, any author): a move,
        β, constraints, the timeline, a snapshot save or delete. Refused (hdeform.Error, code
        ABORTED) when a later change touched what it would revert. discard_timeline: as in
        constrain(), for a step that changed the constraints."""
        self.info = self._call("Undo", pb.UndoRequest(name=self.name, client_id=self.client_id,
                                                      step=step,
                                                      discard_timeline=discard_timeline))
        return self

    def redo(self, step=0, discard_timeline=False):
        """Re-apply this script's latest undone change (or undone step `step`)."""
        self.info = self._call("Redo", pb.UndoRequest(name=self.name, client_id=self.client_id,
                                                      step=step,
                                                      discard_timeline=discard_timeline))
        return self

    def history(self, limit=None):
        """The session's history steps, newest first (hdeform.v1.HistoryStep messages: id,
        kind, author, time_unix_ms, summary, undone, …); all of them, or the newest `limit`."""
        steps, token = [], ""
        while limit is None or len(steps) < limit:
            page = self._call("ListHistory", pb.ListHistoryRequest(
                name=self.name, page_size=500 if limit is None else min(500, limit - len(steps)),
                page_token=token))
            steps.extend(page.steps)
            token = page.next_page_token
            if not token:
                break
        return steps

    def save_snapshot(self, name):
        """Keep the constraints, β and transforms under `name` (replaces one of that name)."""
        return self._call("SaveSnapshot", pb.SaveSnapshotRequest(
            name=self.name, snapshot=name, client_id=self.client_id))

    def snapshots(self):
        """{name: hdeform.v1.NamedSnapshot} of this session."""
        r = self._call("ListSnapshots", pb.ListSnapshotsRequest(name=self.name))
        return {s.name: s for s in r.snapshots}

    def restore_snapshot(self, name, discard_timeline=False):
        """Make snapshot `name` the session's state (an undoable history step).
        discard_timeline: as in constrain(), when its constraints differ."""
        self.info = self._call("RestoreSnapshot", pb.RestoreSnapshotRequest(
            name=self.name, snapshot=name, client_id=self.client_id,
            discard_timeline=discard_timeline))
        return self

    def delete_snapshot(self, name):
        """Remove snapshot `name` (an undoable history step: undo() brings it back)."""
        self._call("DeleteSnapshot", pb.DeleteSnapshotRequest(name=self.name, snapshot=name,
                                                              client_id=self.client_id))

    # --- timeline and animation (docs/api.md "Timeline and animation") ------------------
    def set_timeline(self, keys, easing="linear"):
        """Replace the session's timeline. `keys`: (time_s, transforms) or (time_s, transforms,
        beta) tuples, or dicts time=/transforms=/beta=; transforms one per handle as in
        update(); beta a number in area units or (value, "raw"|"area"), from that key on.
        An empty list clears it. Returns the hdeform.v1.Timeline as stored."""
        t = pb.Timeline(easing={"linear": pb.EASING_LINEAR,
                                "smoothstep": pb.EASING_SMOOTHSTEP}[easing])
        for key in keys:
            if isinstance(key, dict):
                time, transforms, beta = key["time"], key["transforms"], key.get("beta")
            else:
                time, transforms, beta = (tuple(key) + (None,))[:3]
            k = t.keys.add(time_s=float(time))
            k.transforms.extend(self._transforms(transforms, {}))
            if beta is not None:
                value, units = beta if isinstance(beta, tuple) else (beta, "area")
                k.beta.CopyFrom(pb.Beta(value=float(value), units=_units(units)))
        return self._call("SetTimeline", pb.SetTimelineRequest(
            name=self.name, timeline=t, client_id=self.client_id))

    def timeline(self):
        """The session's hdeform.v1.Timeline (no keys: none)."""
        return self._call("GetTimeline", pb.GetTimelineRequest(name=self.name))

    def pose_at(self, time_s):
        """The interpolated pose at `time_s`: an hdeform.v1.Keyframe (transforms per handle,
        beta when a key set one). update(transforms=list(k.transforms)) shows it."""
        return self._call("PoseAt", pb.PoseAtRequest(name=self.name, time_s=float(time_s)))

    def export_animation(self, path=None, fps=24, energies=False, up="y", start=0.0, end=0.0):
        """The timeline as an animated GLB (bytes; also written to `path` if given): one morph
        target per sampled frame, each a full deformation, driven by a weights animation."""
        req = pb.ExportAnimationRequest(
            name=self.name, fps=float(fps), energies=energies, start_s=float(start),
            end_s=float(end), up={"y": pb.UP_AXIS_Y, "z": pb.UP_AXIS_Z}[up])
        try:
            data = b"".join(c.data for c in self.client.stub.ExportAnimation(
                req, metadata=_metadata(self.token, self.name)))
        except grpc.RpcError as e:
            raise from_rpc_error(e) from None
        if path is not None:
            with open(path, "wb") as f:
                f.write(data)
        return data

    def watch(self, encoding="float32"):
        """A Watch: iterate it for every Frame of this session (from any client); it is
        subscribed when watch() returns."""
        return Watch(self, encoding)

    def delete(self):
        self._call("DeleteSession", pb.DeleteSessionRequest(name=self.name))
        self.deleted = True

    def keep(self):
        """Do not delete this session when the Session's or the Client's context exits."""
        self._kept = True
        return self

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if self.owned and not self._kept and not self.deleted:
            self.delete()

    def __repr__(self):
        return f"hdeform.Session({self.name!r}, mesh={self.info.mesh_name!r})"


class Watch:
    """A WatchSession stream: iterate for Frames; `state` is the latest session state
    (hdeform.v1.Session); iteration ends when the session is deleted or cancel() is called."""

    def __init__(self, session, encoding="float32"):
        self.session = session
        self._call = session.client.stub.WatchSession(
            pb.WatchSessionRequest(name=session.name,
                                   format=pb.FrameFormat(encoding=encoding_value(encoding))),
            metadata=_metadata(session.token, session.name))
        self.deleted = False
        self.state = None
        first = self._next()
        if first is not None and first.WhichOneof("event") == "state":
            self.state = first.state

    def _next(self):
        try:
            return next(self._call)
        except StopIteration:
            return None
        except grpc.RpcError as e:
            if e.code() == grpc.StatusCode.CANCELLED:
                return None
            raise from_rpc_error(e) from None

    def __iter__(self):
        while True:
            ev = self._next()
            if ev is None:
                return
            kind = ev.WhichOneof("event")
            if kind == "frame":
                yield decode(ev.frame)
            elif kind == "state":
                self.state = ev.state
            elif kind == "deleted":
                self.deleted = True
                return

    def cancel(self):
        self._call.cancel()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.cancel()
