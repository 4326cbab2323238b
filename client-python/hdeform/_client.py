"""connect(), Client and Session: the hdeform.v1.Deformation service with numpy in and out."""
import decimal
import itertools
import json
import math
import numbers
import os
import struct
import time
import uuid
import warnings
import weakref
from dataclasses import dataclass
from typing import (Any, Callable, Dict, Iterable, Iterator, List, Literal, Optional, Sequence,
                    Tuple, Union)

import grpc
import numpy as np
import numpy.typing as npt

from . import _checks
from ._errors import Error, from_rpc_error
from ._frames import (Encoding, Float64Array, Frame, Int64Array, Measures, PathLike, decode,
                      encoding_value)
from ._meshio import parse_off, ply_bytes, stl_bytes
from ._proto import pb, pb_grpc
from ._records import (HistoryStep, Keyframe, RepairReport, RigExport, Snapshot, Timeline,
                       csv_text)
from ._selectors import RegionLike, Selector, region
from ._server import LocalServer
from ._transforms import Transform, TransformLike, to_transform

CHUNK = 1 << 20  # upload chunks (gRPC's default limit is 4 MiB per message)
_UNITS = {"area": pb.BETA_UNITS_AREA, "raw": pb.BETA_UNITS_RAW}
_FORMATS = {"glb": pb.MESH_FORMAT_GLB, "obj": pb.MESH_FORMAT_OBJ, "off": pb.MESH_FORMAT_OFF,
            "ply": pb.MESH_FORMAT_PLY}
_SAVE_FORMATS = sorted(_FORMATS) + ["stl"]  # STL: written here from the exact mesh (no RPC for it)
_GLB_COMPRESSION = {None: pb.GLB_COMPRESSION_NONE, "none": pb.GLB_COMPRESSION_NONE,
                    "quantized": pb.GLB_COMPRESSION_QUANTIZED,
                    "meshopt": pb.GLB_COMPRESSION_MESHOPT}
# Calls that change nothing: a deadline on any other one may leave its change applied.
_READS = frozenset(("GetSession", "Sweep", "ListHistory", "ListSnapshots", "GetTimeline",
                    "PoseAt"))
_EASINGS = {"linear": pb.EASING_LINEAR, "smoothstep": pb.EASING_SMOOTHSTEP}
_UP = {"y": pb.UP_AXIS_Y, "z": pb.UP_AXIS_Z}

WatchEncoding = Literal["float32", "quantized"]  # a watch's frames (shared: no float64)
Timeout = Optional[float]  # seconds; None: the client's call_timeout; math.inf: no deadline
Metadata = Tuple[Tuple[str, str], ...]


def _timeout_seconds(timeout: Optional[float], what: str = "timeout") -> Optional[float]:
    """None (no deadline) or seconds > 0; math.inf means no deadline."""
    if timeout is None:
        return None
    t = _checks.number(timeout, what, finite=False)
    if not t > 0:
        raise ValueError(f"{what}: seconds > 0, None or math.inf (no deadline), got {t!r}")
    return None if math.isinf(t) else t


class _Deadline:
    """One deadline over every RPC of a public call (a retry, history's pages), so `timeout`
    bounds the whole call."""

    def __init__(self, timeout: Optional[float], method: str,
                 expired: str = "no answer within") -> None:
        self.timeout = timeout
        self.method = method
        self.expired = expired
        self._end = None if timeout is None else time.monotonic() + timeout

    def remaining(self) -> Optional[float]:
        # never 0 or less: gRPC then answers DEADLINE_EXCEEDED itself, the error we want
        return None if self._end is None else max(self._end - time.monotonic(), 1e-6)

    def error(self, e: grpc.RpcError, change: bool = False) -> Error:
        """The hdeform.Error for a grpc.RpcError, naming the timeout when it expired."""
        err = from_rpc_error(e)
        if err.code == grpc.StatusCode.DEADLINE_EXCEEDED and self.timeout is not None:
            msg = (f"{self.method}: {self.expired} timeout={self.timeout:g} s "
                   f"(gRPC: {err.message or 'deadline exceeded'})")
            if change:
                msg += "; the server may still apply the change"
            err = type(err)(msg, err.code)
        return err


def _rpc(fn: Callable[..., Any], *args: Any, deadline: Optional[_Deadline] = None,
         change: bool = False, **kwargs: Any) -> Any:
    try:
        return fn(*args, timeout=deadline.remaining() if deadline else None, **kwargs)
    except grpc.RpcError as e:
        raise (deadline.error(e, change) if deadline else from_rpc_error(e)) from None


def _rpc_bytes(fn: Callable[..., Any], request: Any, deadline: _Deadline,
               metadata: Metadata) -> bytes:
    """A server stream of chunks (GetMesh, ExportAnimation) joined into bytes."""
    try:
        return b"".join(c.data for c in fn(request, metadata=metadata,
                                           timeout=deadline.remaining()))
    except grpc.RpcError as e:
        raise deadline.error(e) from None


def _rpc_chunks_first(fn: Callable[..., Any], request: Any, deadline: _Deadline,
                      metadata: Metadata) -> Tuple[bytes, Any]:
    """A server stream of chunks joined into bytes, and its first chunk (ExportRig sets its
    rig_report; None for an empty stream)."""
    first: Any = None
    parts: List[bytes] = []
    try:
        for c in fn(request, metadata=metadata, timeout=deadline.remaining()):
            if first is None:
                first = c
            parts.append(c.data)
    except grpc.RpcError as e:
        raise deadline.error(e) from None
    return b"".join(parts), first


def _metadata(token: Optional[str], session: Optional[str] = None) -> Metadata:
    """Call metadata: the token, and for a call of a session its id as `x-session-id`, by
    which a load balancer sends every call of a session to the replica that holds it
    (docs/deployment.md "Session affinity")."""
    md: Metadata = (("authorization", f"Bearer {token}"),) if token else ()
    if session:
        md += (("x-session-id", session.split("/", 1)[-1]),)
    return md


def _units(units: str, what: str = "units") -> int:
    return int(_UNITS[_checks.choice(units, _UNITS, what)])


LocalBeta = Dict[str, Any]  # {"region": …, "beta": b, "falloff_radius": r}

RepairLike = Union[bool, float]  # upload(repair=…): True (merge tolerance 0) or the tolerance
_MAX_MERGE_TOLERANCE = 0.01  # of the bounding-box diagonal (docs/api.md "Repair")
# Refusals of an upload that the server's repair may fix (as the CLI's `--repair` hint);
# non-manifold edges and inconsistent orientation are not repaired.
_REPAIRABLE = ("zero-area triangles", "duplicate triangles", "non-manifold vertex")
_REPAIR_HINT = " (upload with repair=True may fix it)"


def _repair_proto(repair: object) -> Any:
    """The header's MeshRepair for upload(repair=…), or None for no repair: checked here."""
    if isinstance(repair, (bool, np.bool_)):
        return pb.MeshRepair() if repair else None
    tolerance = float(repair) if isinstance(repair, numbers.Real) else math.nan
    if not (math.isfinite(tolerance) and 0 <= tolerance <= _MAX_MERGE_TOLERANCE):
        raise ValueError(f"repair: True, False or a merge tolerance in [0, "
                         f"{_MAX_MERGE_TOLERANCE:g}] (a fraction of the bounding-box "
                         f"diagonal), got {repair!r:.60}")
    return pb.MeshRepair(merge_tolerance=tolerance)


def _beta_proto(value: Union[float, str], units: str = "area",
                local: Optional[Sequence[LocalBeta]] = None,
                vertex_count: Optional[int] = None) -> Any:
    # Checked here, before the RPC (and the factorization it starts).
    b = pb.Beta(units=_units(units))
    if isinstance(value, str):
        if value != "auto":
            raise ValueError(f"beta: a number in [0, 1) or 'auto', got {value!r}")
        b.automatic = True
    else:
        b.value = _checks.beta(value, "beta")
    if local is not None and not isinstance(local, (list, tuple)):
        raise TypeError("local: expected a list of {'region': …, 'beta': b, "
                        f"'falloff_radius': r}} dicts, got {type(local).__name__}")
    for i, entry in enumerate(local or ()):
        what = f"local[{i}]"
        if not isinstance(entry, dict) or "region" not in entry or "beta" not in entry:
            raise TypeError(f"{what}: expected a dict with 'region' and 'beta' (and "
                            f"'falloff_radius'), got {entry!r:.80}")
        unknown = set(entry) - {"region", "beta", "falloff_radius"}
        if unknown:
            raise ValueError(f"{what}: unknown keys {sorted(unknown)}")
        radius = _checks.number(entry.get("falloff_radius", 0.0), f"{what}.falloff_radius")
        if radius < 0:
            raise ValueError(f"{what}.falloff_radius: must be >= 0, got {radius!r}")
        b.local.append(pb.LocalBeta(
            region=region(entry["region"], f"{what}.region", vertex_count),
            beta=_checks.beta(entry["beta"], f"{what}.beta"), falloff_radius=radius))
    return b


def _betas(betas: Iterable[float], what: str = "betas") -> List[float]:
    if isinstance(betas, (str, bytes)) or not hasattr(betas, "__iter__"):
        raise TypeError(f"{what}: expected a list of numbers, got {type(betas).__name__}")
    values = [_checks.beta(b, f"{what}[{i}]") for i, b in enumerate(betas)]
    if not values:
        raise ValueError(f"{what}: no values")
    return values


# The CLI's sweep CSV (client-cli/output.cpp, sweep_csv): these column names, β in its
# shortest round-trip form (std::to_chars), measures as "%.17g", flips as an integer, "\n".
_CSV_COLUMNS = ["beta", "E", "E_iso_N", "E_conf_N", "E_area_pct", "max_e_iso", "max_e_conf",
                "max_ef2", "flips"]


def _shortest(v: float) -> str:
    """std::to_chars(double): the shortest digits that read back as v, in fixed or
    scientific notation, whichever is shorter (fixed on a tie); "0", not Python's "0.0"."""
    if not math.isfinite(v):
        return "nan" if math.isnan(v) else ("-inf" if v < 0 else "inf")
    if v == 0:
        return "-0" if math.copysign(1.0, v) < 0 else "0"
    sign, digits, exponent = decimal.Decimal(repr(v)).normalize().as_tuple()
    exp = int(exponent)  # finite here: never 'n', 'N' or 'F'
    ds = "".join(map(str, digits))
    if exp >= 0:
        fixed = str(int(abs(v)))  # libstdc++ prints an integral value's exact digits
    elif len(ds) + exp > 0:
        fixed = ds[:len(ds) + exp] + "." + ds[len(ds) + exp:]
    else:
        fixed = "0." + "0" * -(len(ds) + exp) + ds
    e = exp + len(ds) - 1
    sci = ds[0] + ("." + ds[1:] if len(ds) > 1 else "") + f"e{'-' if e < 0 else '+'}{abs(e):02d}"
    return ("-" if sign else "") + (fixed if len(fixed) <= len(sci) else sci)


@dataclass(frozen=True)
class LibraryMesh:
    """A mesh of the server's library: its name (for Client.open), its path on the server,
    and whether a benchmark .sel/.def comes with it."""
    name: str
    path: str
    has_benchmark: bool


@dataclass(frozen=True)
class SweepRow:
    """One β of a sweep and the measures at it."""
    beta: float
    measures: Measures


class SweepResult(List[SweepRow]):
    """Sweep rows (SweepRow) in request order. records() and to_dataframe() use the Measures
    field names (`columns`); to_csv() writes the CLI's CSV (`csv_columns`)."""

    columns: List[str] = ["beta", "e", "e_iso_n", "e_conf_n", "e_area_pct", "max_e_iso",
                          "max_e_conf", "max_ef2", "flips"]
    csv_columns: List[str] = _CSV_COLUMNS
    units: str = "area"  # the sweep's β units

    def records(self) -> List[Dict[str, Union[float, int]]]:
        """One dict per row: beta and the seven measures."""
        return [dict(beta=r.beta, **r.measures.as_dict()) for r in self]

    def to_dataframe(self) -> Any:
        """A pandas DataFrame (needs pandas: apt-get install python3-pandas)."""
        try:
            import pandas  # noqa: PLC0415 - optional dependency
        except ImportError as e:
            raise ImportError(
                "SweepResult.to_dataframe() needs pandas: apt-get install python3-pandas "
                "(for Debian's /usr/bin/python3 or a venv made with --system-site-packages); "
                "records() and to_csv() need nothing", name="pandas") from e
        return pandas.DataFrame.from_records(self.records(), columns=self.columns)

    def plot(self, ax: Any = None, path: Optional[PathLike] = None,
             measures: Sequence[str] = ("e_iso_n", "e_conf_n", "max_e_iso", "max_e_conf"),
             logy: bool = True) -> Any:
        """A matplotlib Figure of `measures` (Measures field names) against β, one line each
        (log scale with `logy`), β's where a solve has flipped triangles marked with an ×.
        `ax`: draw on that Axes (its Figure is returned); `path`: also save the figure (PNG,
        SVG, PDF by extension; without `ax` the figure is then made without pyplot, so no
        window opens). Needs matplotlib (apt-get install python3-matplotlib)."""
        from ._plot import plot_sweep
        return plot_sweep(self, ax=ax, path=path, measures=measures, logy=logy)

    def to_csv(self, path: Optional[PathLike] = None) -> Optional[str]:
        """The rows as `hdeform sweep --csv` writes them (same header and numbers): written
        to `path`, or returned as a string without one."""
        lines = [",".join(_CSV_COLUMNS)]
        for r in self:
            m = r.measures
            lines.append(",".join(
                [_shortest(r.beta)] +
                [format(float(v), ".17g") for v in (m.e, m.e_iso_n, m.e_conf_n, m.e_area_pct,
                                                      m.max_e_iso, m.max_e_conf, m.max_ef2)] +
                [str(int(m.flips))]))
        return csv_text(lines, path)


class Client:
    """A connection to an hdeform-server (make one with hdeform.connect()). As a context
    manager it deletes, on exit, the sessions it created (unless kept with Session.keep()) and
    stops its private server. `call_timeout`: the deadline in seconds of every call that does
    not pass its own `timeout=` (None: no deadline)."""

    def __init__(self, address: str, token: Optional[str] = None, credentials: Any = None,
                 server: Optional[LocalServer] = None, ready_timeout: Optional[float] = 30.0,
                 call_timeout: Optional[float] = None) -> None:
        self.address = address
        self.token = token
        self.server = server
        self.call_timeout = _timeout_seconds(call_timeout, "call_timeout")
        options = [("grpc.max_receive_message_length", -1),
                   ("grpc.max_send_message_length", -1)]
        if credentials is not None:
            self.channel = grpc.secure_channel(address, credentials, options=options)
        else:
            self.channel = grpc.insecure_channel(address, options=options)
        self.stub = pb_grpc.DeformationStub(self.channel)
        self._created: "weakref.WeakSet[Session]" = weakref.WeakSet()
        if ready_timeout:
            try:
                grpc.channel_ready_future(self.channel).result(timeout=ready_timeout)
            except grpc.FutureTimeoutError:
                self.close()
                raise Error(f"no hdeform-server answers at {address} "
                            f"(waited {ready_timeout:g} s)",
                            grpc.StatusCode.UNAVAILABLE) from None

    def _deadline(self, timeout: Timeout, method: str) -> _Deadline:
        """A call's deadline: its own timeout=, else call_timeout; math.inf: none."""
        if timeout is None:
            return _Deadline(self.call_timeout, method)
        return _Deadline(_timeout_seconds(timeout), method)

    # --- sessions -------------------------------------------------------------------------
    def meshes(self, timeout: Timeout = None) -> List[LibraryMesh]:
        """The server's mesh library."""
        r = _rpc(self.stub.ListMeshes, pb.ListMeshesRequest(),
                 deadline=self._deadline(timeout, "ListMeshes"))
        return [LibraryMesh(str(m.name), str(m.path), bool(m.has_benchmark)) for m in r.meshes]

    def _create(self, header: Any, data: bytes = b"", timeout: Timeout = None) -> "Session":
        # The id is chosen here so that the creating call is routed by it, like every later
        # call of the session (docs/deployment.md).
        repair = header.HasField("repair")
        if not header.session_id:
            header.session_id = uuid.uuid4().hex[:24]
        def requests() -> Iterator[Any]:
            yield pb.CreateSessionRequest(header=header)
            for i in range(0, len(data), CHUNK):
                yield pb.CreateSessionRequest(chunk=data[i:i + CHUNK])
        try:
            info = _rpc(self.stub.CreateSession, requests(),
                        metadata=_metadata(None, header.session_id),
                        deadline=self._deadline(timeout, "CreateSession"), change=True)
        except Error as e:
            if (repair or header.WhichOneof("source") != "filename" or
                    e.code != grpc.StatusCode.INVALID_ARGUMENT or
                    not e.message.startswith(_REPAIRABLE)):
                raise
            raise type(e)(e.message + _REPAIR_HINT, e.code) from None
        s = Session(self, info, str(info.edit_token), view_token=str(info.view_token),
                    owned=True)
        if repair:  # only CreateSession's answer has the report
            s._repair = RepairReport.from_proto(info.repair)
        self._created.add(s)
        return s

    def open(self, mesh: str, session_id: str = "", timeout: Timeout = None) -> "Session":
        """A new session on a library mesh (a name from meshes(), e.g. "cactus")."""
        if not isinstance(mesh, str):
            raise TypeError(f"mesh: a library mesh name (str), got {type(mesh).__name__}")
        return self._create(pb.CreateSessionHeader(library_mesh=mesh, session_id=session_id),
                            timeout=timeout)

    def upload(self, V: npt.ArrayLike, F: Union[npt.ArrayLike, Sequence[Sequence[int]]],
               session_id: str = "", filename: str = "mesh.ply",
               timeout: Timeout = None, repair: RepairLike = False) -> "Session":
        """A new session on the mesh (V n×3, F m×3 triangles; quads and other polygons are
        fan-triangulated as the server's file readers do, see hdeform.triangulate), sent as a
        binary PLY of doubles: vertex ids and frame rows are V's rows (unless a repair
        renumbers them: Session.repair.base_to_input). repair: True (merge equal positions)
        or a merge tolerance in [0, 0.01] of the bounding-box diagonal asks the server to
        repair the mesh first (docs/api.md "Repair"); the report is Session.repair."""
        header = pb.CreateSessionHeader(session_id=session_id)
        r = _repair_proto(repair)  # checked before the mesh is even converted
        if r is not None:
            header.repair.CopyFrom(r)
        data = ply_bytes(V, F)
        header.filename, header.total_bytes = filename, len(data)
        return self._create(header, data, timeout)

    def upload_meshio(self, mesh: Any, session_id: str = "", filename: str = "mesh.ply",
                      timeout: Timeout = None, repair: RepairLike = False) -> "Session":
        """A new session on a meshio.Mesh: upload(*hdeform.from_meshio(mesh)) (its triangle
        cells; quads and polygons fan-triangulated; points and frame rows in mesh.points'
        order). repair: as upload()."""
        _repair_proto(repair)
        from ._interop import from_meshio
        V, F = from_meshio(mesh)
        return self.upload(V, F, session_id=session_id, filename=filename, timeout=timeout,
                           repair=repair)

    def upload_file(self, path: PathLike, session_id: str = "",
                    timeout: Timeout = None, repair: RepairLike = False) -> "Session":
        """A new session on a mesh file (.obj .off .ply .stl .glb, or a self-contained .gltf).
        repair: as upload()."""
        header = pb.CreateSessionHeader(session_id=session_id)
        r = _repair_proto(repair)
        if r is not None:
            header.repair.CopyFrom(r)
        with open(os.fspath(path), "rb") as f:
            data = f.read()
        header.filename = os.path.basename(os.fspath(path))
        header.total_bytes = len(data)
        return self._create(header, data, timeout)

    def session(self, name: str, token: Optional[str] = None,
                timeout: Timeout = None) -> "Session":
        """Attach to an existing session ("sessions/ID" or "ID") with its edit or view token
        (default: the client's token, e.g. the operator token)."""
        token = token if token is not None else self.token
        info = _rpc(self.stub.GetSession, pb.GetSessionRequest(name=name),
                    metadata=_metadata(token, name),
                    deadline=self._deadline(timeout, "GetSession"))
        return Session(self, info, token, owned=False)

    def sessions(self, timeout: Timeout = None) -> List[str]:
        """Names of the sessions the client's token opens (all with the operator token)."""
        r = _rpc(self.stub.ListSessions, pb.ListSessionsRequest(),
                 metadata=_metadata(self.token),
                 deadline=self._deadline(timeout, "ListSessions"))
        return [str(s.name) for s in r.sessions]

    # --- lifetime -------------------------------------------------------------------------
    def close(self) -> None:
        """Close the channel and stop the private server (if any)."""
        self.channel.close()
        if self.server is not None:
            self.server.stop()

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc: object) -> None:
        try:
            for s in list(self._created):
                if not s._kept and not s.deleted:
                    try:
                        s.delete()
                    except Error:
                        pass
        finally:
            self.close()

    def __repr__(self) -> str:
        return f"hdeform.Client({self.address!r}{', private server' if self.server else ''})"


def connect(address: Optional[str] = None, *, token: Optional[str] = None,
            server: Optional[PathLike] = None, mesh_dir: Optional[PathLike] = None,
            state_dir: Optional[PathLike] = None, server_args: Sequence[str] = (),
            credentials: Any = None, timeout: float = 30.0,
            call_timeout: Optional[float] = None) -> Client:
    """A Client. With an address ("host:port"): that server, presenting `token` (an operator
    token, or a session token for Client.session()). Without: a private hdeform-server
    (`server`, else $HDEFORM_SERVER, else the build tree's, else hdeform-server on PATH; see
    hdeform.find_server) on a free loopback port (it reports the port through --ready-file),
    with a random operator token the client presents, stopped by close()/the context's
    exit/at exit, and with this process however it ends (--exit-with-parent).
    That server gets a clean environment (none of the caller's HDEFORM_* settings): configure
    it with `server_args`. `timeout`: seconds to start the server / reach it. `call_timeout`:
    the default deadline of every later call (None: none; a call's timeout= overrides it)."""
    call_timeout = _timeout_seconds(call_timeout, "call_timeout")  # before starting anything
    if address is not None:
        return Client(address, token=token, credentials=credentials, ready_timeout=timeout,
                      call_timeout=call_timeout)
    srv = LocalServer(server, mesh_dir=mesh_dir, state_dir=state_dir, args=server_args,
                      timeout=timeout)
    try:
        return Client(srv.address, token=token or srv.admin_token, server=srv,
                      ready_timeout=timeout, call_timeout=call_timeout)
    except BaseException:
        srv.stop(keep_log=True)
        raise


class Session:
    """One server session. Keeps its tokens (`token` is the one it presents; `edit_token` /
    `view_token` when this client created it). As a context manager it deletes the session
    on exit if this client created it. Every method that calls the server takes `timeout=`
    (seconds; default: the client's call_timeout, None = no deadline)."""

    def __init__(self, client: Client, info: Any, token: Optional[str],
                 view_token: Optional[str] = None, owned: bool = False) -> None:
        # Who this script is in the session's history and to other editors: its changes
        # carry it, and undo() / redo() act on its own steps.
        self.client_id = "py-" + uuid.uuid4().hex[:12]
        self.client = client
        self.info: Any = info  # the latest hdeform.v1.Session (protobuf)
        self.name: str = str(info.name)
        self.token = token
        self.edit_token = token if owned else None
        self.view_token = view_token
        self.owned = owned
        self.deleted = False
        self._kept = False
        self._sequence = itertools.count(1)
        self._triangles: Optional[Int64Array] = None
        self._repair: Optional[RepairReport] = None

    def _call(self, method: str, request: Any,
              timeout: Union[Timeout, _Deadline] = None) -> Any:
        """One unary RPC of this session; `timeout`: a public call's timeout= or its
        _Deadline (shared by the RPCs of one public call)."""
        deadline = (timeout if isinstance(timeout, _Deadline)
                    else self.client._deadline(timeout, method))
        # A change carries a request id, so one retry after UNAVAILABLE (the answer may have
        # been lost after the server applied it) is answered, never applied twice.
        retry = "request_id" in request.DESCRIPTOR.fields_by_name
        change = method not in _READS
        if retry and not request.request_id:
            request.request_id = uuid.uuid4().hex
        stub = getattr(self.client.stub, method)
        md = _metadata(self.token, self.name)
        try:
            return _rpc(stub, request, metadata=md, deadline=deadline, change=change)
        except Error as e:
            if not retry or e.code != grpc.StatusCode.UNAVAILABLE:
                raise
            time.sleep(0.5)
            return _rpc(stub, request, metadata=md, deadline=deadline, change=change)

    # --- state ----------------------------------------------------------------------------
    @property
    def id(self) -> str:
        """The session id (its name without "sessions/")."""
        return self.name.split("/", 1)[-1]

    def refresh(self, timeout: Timeout = None) -> "Session":
        """Re-read the session's state (self.info) from the server."""
        self.info = self._call("GetSession", pb.GetSessionRequest(name=self.name), timeout)
        return self

    @property
    def repair(self) -> Optional[RepairReport]:
        """What the server's repair changed (an hdeform.RepairReport) when this client
        uploaded the mesh with repair=…; None otherwise (no repair asked, or a session
        attached with Client.session())."""
        return self._repair

    @property
    def vertex_count(self) -> int:
        """Vertices in frame order (the base GLB's): the rows of Frame.V."""
        return int(self.info.vertex_count)

    @property
    def triangle_count(self) -> int:
        return int(self.info.triangle_count)

    @property
    def version(self) -> int:
        return int(self.info.version)

    @property
    def mesh_name(self) -> str:
        return str(self.info.mesh_name)

    @property
    def handle_count(self) -> int:
        return len(self.info.constraints.handles)

    @property
    def fixed(self) -> Int64Array:
        """The fixed vertices' engine ids (sorted)."""
        return np.asarray(self.info.constraints.fixed.ids, dtype=np.int64)

    @property
    def handles(self) -> List[Int64Array]:
        """Each handle's engine vertex ids (sorted)."""
        return [np.asarray(h.ids, dtype=np.int64) for h in self.info.constraints.handles]

    @property
    def pivots(self) -> Float64Array:
        """Each handle's default pivot (rest centroid), k×3."""
        return np.array([[p.x, p.y, p.z] for p in self.info.pivots],
                        dtype=np.float64).reshape(-1, 3)

    @property
    def bbox(self) -> Float64Array:
        """The rest bounding box, 2×3 (min, max)."""
        a, b = self.info.bbox_min, self.info.bbox_max
        return np.array([[a.x, a.y, a.z], [b.x, b.y, b.z]], dtype=np.float64)

    # --- meshes ---------------------------------------------------------------------------
    def mesh_bytes(self, format: str = "glb", rest: bool = False,  # noqa: A002 - proto's name
                   compression: Optional[str] = None,
                   timeout: Union[Timeout, _Deadline] = None) -> bytes:
        """The rest or current mesh as a file (glb, obj, off, ply, stl). compression (GLB
        only): "quantized" (KHR_mesh_quantization) or "meshopt" (EXT_meshopt_compression),
        see docs/api.md "Compressed GLB"; hdeform does not read those back. STL is written
        here from the exact mesh (binary, float32: STL's own precision)."""
        _checks.choice(format, _SAVE_FORMATS, "format")
        _checks.choice(compression, _GLB_COMPRESSION, "compression")
        if format == "stl":
            if compression not in (None, "none"):
                raise ValueError("compression: GLB only, not for STL")
            V, F = self.mesh(rest=rest, timeout=timeout)
            return stl_bytes(V, F)
        req = pb.GetMeshRequest(name=self.name, rest=rest, format=_FORMATS[format],
                                glb_compression=_GLB_COMPRESSION[compression])
        deadline = (timeout if isinstance(timeout, _Deadline)
                    else self.client._deadline(timeout, "GetMesh"))
        return _rpc_bytes(self.client.stub.GetMesh, req, deadline,
                          _metadata(self.token, self.name))

    def mesh(self, rest: bool = False, timeout: Union[Timeout, _Deadline] = None
             ) -> Tuple[Float64Array, Int64Array]:
        """(V float64 n×3, F int64 m×3) of the rest or current mesh, exact doubles, in engine
        vertex order (= Frame.V order except for glTF uploads)."""
        return parse_off(self.mesh_bytes("off", rest=rest, timeout=timeout))

    def rest(self, timeout: Timeout = None) -> Tuple[Float64Array, Int64Array]:
        """mesh(rest=True)."""
        return self.mesh(rest=True, timeout=timeout)

    def triangles(self, timeout: Timeout = None) -> Int64Array:
        """The triangles (m×3 int64) in frame order: those of the base GLB
        (GetMesh(rest=True, GLB)), which index the rows of Frame.V for every upload, glTF
        too. Read once and kept (a session's triangles never change); Frame.F and
        Frame.to_meshio() use it."""
        if self._triangles is None:
            self._triangles = _glb_triangles(self.mesh_bytes("glb", rest=True, timeout=timeout))
            if len(self._triangles) != self.triangle_count:
                raise Error(f"GetMesh(rest, GLB): {len(self._triangles)} triangles, but the "
                            f"session has {self.triangle_count}")
        return self._triangles

    def save(self, path: PathLike, rest: bool = False, compression: Optional[str] = None,
             timeout: Timeout = None) -> None:
        """Write the current (or rest) mesh; the extension picks the format (.glb .obj .off
        .ply .stl). compression: as mesh_bytes (a .glb only). OBJ, OFF and PLY are the
        server's own files (GetMesh), byte for byte: an upload's quads and other polygons come
        back as the same faces, with the vertices in engine order (exact doubles); STL is
        written here, as triangles."""
        ext = os.path.splitext(os.fspath(path))[1].lower().lstrip(".")
        if ext not in _SAVE_FORMATS:
            raise ValueError(f"path: the extension picks the format, one of "
                             f"{' '.join('.' + f for f in _SAVE_FORMATS)}, got {os.fspath(path)!r}")
        data = self.mesh_bytes(ext, rest=rest, compression=compression, timeout=timeout)
        with open(os.fspath(path), "wb") as f:
            f.write(data)

    # --- editing --------------------------------------------------------------------------
    def constrain(self, fixed: Optional[RegionLike] = None,
                  handles: Sequence[RegionLike] = (), expected_version: int = 0,
                  discard_timeline: bool = False, timeout: Timeout = None) -> "Session":
        """Set the fixed region and the handle regions. A region: a selector (hdeform.ids,
        box, sphere, half_space, sel_file, …), a dict ({"box": (min, max)}), an id array, a
        boolean mask over the vertices, or a list of selectors (their union). Resets every
        handle transform to identity. New constraints drop the timeline's keys (undo() brings
        them back); keys another client set are dropped only with discard_timeline=True (else
        hdeform.Error ABORTED)."""
        # An array or a selector here would be read as one handle per element: refused.
        if isinstance(handles, (Selector, dict, np.ndarray, str, bytes)) or not hasattr(
                handles, "__iter__"):
            raise TypeError("handles: expected a list with one region per handle, got "
                            f"{type(handles).__name__} (a single handle: handles=[region])")
        handles = list(handles)
        n = self.vertex_count
        c = pb.Constraints(handles=[region(h, f"handles[{i}]", n) for i, h in enumerate(handles)])
        if fixed is not None:
            c.fixed.CopyFrom(region(fixed, "fixed", n))
        self.info = self._call("SetConstraints", pb.SetConstraintsRequest(
            name=self.name, constraints=c, expected_version=expected_version,
            client_id=self.client_id, discard_timeline=discard_timeline), timeout)
        return self

    @property
    def beta(self) -> float:
        """β's value (the pick when automatic; see beta_automatic, beta_units). Assigning
        (a number in area units, or "auto") is a shorthand for set_beta(value): an RPC and a
        new factorization, with the client's call_timeout."""
        return float(self.info.beta.value)

    @beta.setter
    def beta(self, value: Union[float, str]) -> None:
        self.set_beta(value)

    @property
    def beta_automatic(self) -> bool:
        return bool(self.info.beta.automatic)

    @property
    def beta_units(self) -> str:
        return "raw" if self.info.beta.units == pb.BETA_UNITS_RAW else "area"

    def set_beta(self, value: Union[float, str], units: str = "area",
                 local: Optional[Sequence[LocalBeta]] = None, expected_version: int = 0,
                 timeout: Timeout = None) -> "Session":
        """β = value (0 ≤ β < 1, or "auto") in `units` ("area" or "raw"); `local`: a list of
        {"region": …, "beta": b, "falloff_radius": r}. The server refactors the system: on a
        large mesh this takes a while, which `timeout` bounds."""
        beta = _beta_proto(value, units, local, self.vertex_count)  # checked before the RPC
        self.info = self._call("SetBeta", pb.SetBetaRequest(
            name=self.name, beta=beta, expected_version=expected_version,
            client_id=self.client_id), timeout)
        return self

    def _transforms(self, transforms: Union[TransformLike, Sequence[TransformLike]],
                    single: Dict[str, Any]) -> List[Any]:
        if transforms is not None:
            if any(v is not None for v in single.values()):
                raise TypeError("update: pass either transforms=[...] or rotate=/translate=/…")
            items: Any = [transforms] if isinstance(transforms, (Transform, dict)) else transforms
            return [to_transform(t).to_proto() for t in items]
        t = Transform(**single)
        k = self.handle_count
        if k != 1 and any(v is not None for v in single.values()):
            raise TypeError(f"update: the session has {k} handles; pass transforms=[one per "
                            "handle] (hdeform.transform(...), dicts, 4×4 matrices or None)")
        return [t.to_proto()] * k

    def update(self, transforms: Optional[Sequence[TransformLike]] = None, *,
               rotate: Optional[npt.ArrayLike] = None,
               translate: Optional[npt.ArrayLike] = None,
               scale: Optional[npt.ArrayLike] = None, pivot: Optional[npt.ArrayLike] = None,
               matrix: Optional[npt.ArrayLike] = None, energies: bool = False,
               encoding: Encoding = "float64", double: Optional[bool] = None,
               dragging: bool = False, expected_version: int = 0,
               timeout: Timeout = None) -> Frame:
        """Move the handles and solve: a Frame. For one handle pass rotate= (quaternion
        w, x, y, z or 3×3), translate=, scale=, pivot=, matrix= (4×4); for several,
        transforms=[one per handle]. encoding: "float64" (default: frame.V and frame.N are
        the server's doubles, exactly, in one call), "float32" or "quantized" (fewer bytes).
        energies=True: per-triangle energies too. double: deprecated, not needed (frames are
        float64 by default): True is accepted with a DeprecationWarning and changes nothing."""
        if double is not None:
            if not isinstance(double, bool):
                raise TypeError(f"double: expected a bool, got {type(double).__name__}")
            if double and encoding != "float64":
                raise ValueError(f"double=True (deprecated) asks for exact doubles, but "
                                 f"encoding={encoding!r}: drop double= (frames are float64 by "
                                 "default)")
            if double:
                warnings.warn("update(double=True) is deprecated and not needed: frames are "
                              "float64 by default (encoding='float64'), the server's doubles "
                              "in one call", DeprecationWarning, stacklevel=2)
        fmt = pb.FrameFormat(encoding=encoding_value(encoding))
        ts = self._transforms(transforms, dict(rotate=rotate, translate=translate, scale=scale,
                                                pivot=pivot, matrix=matrix))
        deadline = self.client._deadline(timeout, "UpdateHandles")
        seq = next(self._sequence)
        raw = self._call("UpdateHandles", pb.UpdateHandlesRequest(
            name=self.name, sequence=seq, transforms=ts, energies=energies, dragging=dragging,
            expected_version=expected_version, client_id=self.client_id, format=fmt), deadline)
        frame = decode(raw, self.vertex_count, self.triangle_count, self.triangles)
        self.info.version = raw.version
        return frame

    def sweep(self, betas: Iterable[float], units: str = "area",
              transforms: Optional[Sequence[TransformLike]] = None,
              timeout: Timeout = None) -> SweepResult:
        """Measures for each β (the session is not changed) at the current transforms or at
        `transforms` (one per handle): a SweepResult (list of SweepRow; .to_csv(),
        .to_dataframe())."""
        req = pb.SweepRequest(name=self.name, betas=_betas(betas), units=_units(units))
        if transforms is not None:
            req.transforms.extend(self._transforms(transforms, {}))
        r = self._call("Sweep", req, timeout)
        result = SweepResult(SweepRow(float(row.beta), Measures.from_proto(row.measures))
                             for row in r.rows)
        result.units = units
        return result

    # --- history and snapshots (docs/api.md "History and snapshots") --------------------
    def undo(self, step: int = 0, discard_timeline: bool = False,
             timeout: Timeout = None) -> "Session":
        """Revert this script's latest change (or history step `step`, any author): a move,
        β, constraints, the timeline, a snapshot save or delete. Refused (hdeform.Error, code
        ABORTED) when a later change touched what it would revert. discard_timeline: as in
        constrain(), for a step that changed the constraints."""
        self.info = self._call("Undo", pb.UndoRequest(name=self.name, client_id=self.client_id,
                                                      step=step,
                                                      discard_timeline=discard_timeline),
                               timeout)
        return self

    def redo(self, step: int = 0, discard_timeline: bool = False,
             timeout: Timeout = None) -> "Session":
        """Re-apply this script's latest undone change (or undone step `step`)."""
        self.info = self._call("Redo", pb.UndoRequest(name=self.name, client_id=self.client_id,
                                                      step=step,
                                                      discard_timeline=discard_timeline),
                               timeout)
        return self

    def history(self, limit: Optional[int] = None,
                timeout: Timeout = None) -> List[HistoryStep]:
        """The session's history steps, newest first (hdeform.HistoryStep: id, kind ("move",
        "beta", "undo", …), author, time_unix_ms, summary, undone, …); all of them, or the
        newest `limit`. `timeout` bounds all the pages together."""
        deadline = self.client._deadline(timeout, "ListHistory")
        steps: List[HistoryStep] = []
        token = ""
        while limit is None or len(steps) < limit:
            page = self._call("ListHistory", pb.ListHistoryRequest(
                name=self.name, page_size=500 if limit is None else min(500, limit - len(steps)),
                page_token=token), deadline)
            steps.extend(HistoryStep.from_proto(step) for step in page.steps)
            token = page.next_page_token
            if not token:
                break
        return steps

    def save_snapshot(self, name: str, timeout: Timeout = None) -> Snapshot:
        """Keep the constraints, β and transforms under `name` (replaces one of that name);
        returns the hdeform.Snapshot saved."""
        return Snapshot.from_proto(self._call("SaveSnapshot", pb.SaveSnapshotRequest(
            name=self.name, snapshot=name, client_id=self.client_id), timeout))

    def snapshots(self, timeout: Timeout = None) -> Dict[str, Snapshot]:
        """{name: hdeform.Snapshot} of this session."""
        r = self._call("ListSnapshots", pb.ListSnapshotsRequest(name=self.name), timeout)
        return {str(s.name): Snapshot.from_proto(s) for s in r.snapshots}

    def restore_snapshot(self, name: str, discard_timeline: bool = False,
                         timeout: Timeout = None) -> "Session":
        """Make snapshot `name` the session's state (an undoable history step).
        discard_timeline: as in constrain(), when its constraints differ."""
        self.info = self._call("RestoreSnapshot", pb.RestoreSnapshotRequest(
            name=self.name, snapshot=name, client_id=self.client_id,
            discard_timeline=discard_timeline), timeout)
        return self

    def delete_snapshot(self, name: str, timeout: Timeout = None) -> None:
        """Remove snapshot `name` (an undoable history step: undo() brings it back)."""
        self._call("DeleteSnapshot", pb.DeleteSnapshotRequest(name=self.name, snapshot=name,
                                                              client_id=self.client_id),
                   timeout)

    # --- timeline and animation (docs/api.md "Timeline and animation") ------------------
    def set_timeline(self, keys: Sequence[Any], easing: str = "linear",
                     timeout: Timeout = None) -> Timeline:
        """Replace the session's timeline. `keys`: (time_s, transforms) or (time_s, transforms,
        beta) tuples, or dicts time=/transforms=/beta=/easing=; transforms one per handle as in
        update(); beta a number in area units or (value, "raw"|"area"), from that key on;
        easing ("linear" | "smoothstep") the key's own to the next key (default: `easing`).
        An empty list clears it. Returns the hdeform.Timeline as stored."""
        t = pb.Timeline(easing=_EASINGS[_checks.choice(easing, _EASINGS, "easing")])
        for i, key in enumerate(keys):
            if isinstance(key, dict):
                if "time" not in key or "transforms" not in key:
                    raise TypeError(f"keys[{i}]: a dict needs 'time' and 'transforms', got "
                                    f"{sorted(key)}")
                unknown = sorted(set(key) - {"time", "transforms", "beta", "easing"})
                if unknown:
                    raise TypeError(f"keys[{i}]: unknown key(s) {unknown}")
                time_s, transforms, beta = key["time"], key["transforms"], key.get("beta")
                key_easing = key.get("easing")
            elif isinstance(key, (list, tuple)) and len(key) in (2, 3):
                time_s, transforms, beta = (tuple(key) + (None,))[:3]
                key_easing = None
            else:
                raise TypeError(f"keys[{i}]: expected (time_s, transforms[, beta]) or a dict, "
                                f"got {key!r:.80}")
            k = t.keys.add(time_s=_checks.number(time_s, f"keys[{i}] time"))
            k.transforms.extend(self._transforms(transforms, {}))
            if beta is not None:
                value, units = beta if isinstance(beta, tuple) else (beta, "area")
                k.beta.CopyFrom(pb.Beta(value=_checks.beta(value, f"keys[{i}] beta"),
                                        units=_units(units, f"keys[{i}] beta units")))
            if key_easing is not None:
                k.easing = _EASINGS[_checks.choice(key_easing, _EASINGS, f"keys[{i}] easing")]
        return Timeline.from_proto(self._call("SetTimeline", pb.SetTimelineRequest(
            name=self.name, timeline=t, client_id=self.client_id), timeout))

    def timeline(self, timeout: Timeout = None) -> Timeline:
        """The session's hdeform.Timeline (no keys: none)."""
        return Timeline.from_proto(
            self._call("GetTimeline", pb.GetTimelineRequest(name=self.name), timeout))

    def pose_at(self, time_s: float, timeout: Timeout = None) -> Keyframe:
        """The interpolated pose at `time_s`: an hdeform.Keyframe (one hdeform.Transform per
        handle, beta when a key set one). update(transforms=list(k.transforms)) shows it."""
        return Keyframe.from_proto(self._call("PoseAt", pb.PoseAtRequest(
            name=self.name, time_s=_checks.number(time_s, "time_s")), timeout))

    def export_animation(self, path: Optional[PathLike] = None, fps: float = 24,
                         energies: bool = False, up: str = "y", start: float = 0.0,
                         end: float = 0.0, timeout: Timeout = None) -> bytes:
        """The timeline as an animated GLB (bytes; also written to `path` if given): one morph
        target per sampled frame, each a full deformation, driven by a weights animation."""
        req = pb.ExportAnimationRequest(
            name=self.name, fps=_checks.number(fps, "fps"), energies=energies,
            start_s=_checks.number(start, "start"), end_s=_checks.number(end, "end"),
            up=_UP[_checks.choice(up, _UP, "up")])
        data = _rpc_bytes(self.client.stub.ExportAnimation, req,
                          self.client._deadline(timeout, "ExportAnimation"),
                          _metadata(self.token, self.name))
        if path is not None:
            with open(path, "wb") as f:
                f.write(data)
        return data

    def export_rig(self, path: Optional[PathLike] = None, influences: int = 4, up: str = "y",
                   animation: bool = True, timeout: Timeout = None) -> RigExport:
        """The session as a rig: a skinned GLB (hdeform.RigExport.glb; also written to `path`
        if given) with the fixed region as root joint 0 and handle j as joint j + 1 (at its
        pivot), the harmonic fields as skin weights (the top `influences`, 4 or 8, per vertex),
        the joints in the current pose, and with `animation` the timeline's keys as a skeletal
        animation. RigExport.poses: how far linear blend skinning is from the exact solve at
        the current pose and at each key (fractions of the bbox diagonal; to_csv() writes them
        as `hdeform rig --report`). up: "y" or "z", the model's up axis (docs/rig.md)."""
        given: object = influences  # checked as any object: a script may pass anything
        if isinstance(given, (bool, np.bool_)) or not isinstance(given, numbers.Integral):
            raise TypeError(f"influences: expected 4 or 8, got {type(given).__name__}")
        _checks.choice(int(given), (4, 8), "influences")
        flag: object = animation
        if not isinstance(flag, (bool, np.bool_)):
            raise TypeError(f"animation: expected a bool, got {type(flag).__name__}")
        req = pb.ExportRigRequest(name=self.name, influences=int(influences),
                                  up=_UP[_checks.choice(up, _UP, "up")],
                                  skip_animation=not flag)
        data, first = _rpc_chunks_first(self.client.stub.ExportRig, req,
                                        self.client._deadline(timeout, "ExportRig"),
                                        _metadata(self.token, self.name))
        if first is None or not first.HasField("rig_report"):
            raise Error("ExportRig: the server sent no rig report (an older hdeform-server?)")
        rig = RigExport.from_proto(data, first.rig_report)
        if path is not None:
            with open(os.fspath(path), "wb") as f:
                f.write(data)
        return rig

    def watch(self, encoding: WatchEncoding = "float32",
              timeout: Optional[float] = None) -> "Watch":
        """A Watch: iterate it for every Frame of this session (from any client); it is
        subscribed when watch() returns. encoding: "float32" or "quantized" (a watch stream
        shares its frames with every watcher: no "float64"). `timeout`: the stream's whole
        life in seconds (not the client's call_timeout: a watch is meant to last); None =
        until cancelled."""
        return Watch(self, encoding, timeout)

    def delete(self, timeout: Timeout = None) -> None:
        self._call("DeleteSession", pb.DeleteSessionRequest(name=self.name), timeout)
        self.deleted = True

    def keep(self) -> "Session":
        """Do not delete this session when the Session's or the Client's context exits."""
        self._kept = True
        return self

    def __enter__(self) -> "Session":
        return self

    def __exit__(self, *exc: object) -> None:
        if self.owned and not self._kept and not self.deleted:
            self.delete()

    def __repr__(self) -> str:
        return f"hdeform.Session({self.name!r}, mesh={self.info.mesh_name!r})"


class Watch:
    """A WatchSession stream: iterate for Frames; `state` is the latest session state
    (hdeform.v1.Session); iteration ends when the session is deleted or cancel() is called.
    With a timeout, the stream ends with hdeform.DeadlineExceeded when it expires."""

    def __init__(self, session: Session, encoding: WatchEncoding = "float32",
                 timeout: Optional[float] = None) -> None:
        self.session = session
        fmt = pb.FrameFormat(encoding=encoding_value(encoding, "watch encoding",
                                                     ("float32", "quantized")))
        self._deadline = _Deadline(_timeout_seconds(timeout), "WatchSession",
                                   "the stream ended at its")
        self._call = session.client.stub.WatchSession(
            pb.WatchSessionRequest(name=session.name, format=fmt),
            metadata=_metadata(session.token, session.name), timeout=self._deadline.remaining())
        self.deleted = False
        self.state: Any = None  # the latest hdeform.v1.Session (protobuf)
        first = self._next()
        if first is not None and first.WhichOneof("event") == "state":
            self.state = first.state

    def _next(self) -> Any:
        try:
            return next(self._call)
        except StopIteration:
            return None
        except grpc.RpcError as e:
            if e.code() == grpc.StatusCode.CANCELLED:
                return None
            raise self._deadline.error(e) from None

    def __iter__(self) -> Iterator[Frame]:
        while True:
            ev = self._next()
            if ev is None:
                return
            kind = ev.WhichOneof("event")
            if kind == "frame":
                yield decode(ev.frame, self.session.vertex_count,
                             self.session.triangle_count, self.session.triangles)
            elif kind == "state":
                self.state = ev.state
            elif kind == "deleted":
                self.deleted = True
                return

    def cancel(self) -> None:
        self._call.cancel()

    def __enter__(self) -> "Watch":
        return self

    def __exit__(self, *exc: object) -> None:
        self.cancel()


def _glb_triangles(glb: bytes) -> Int64Array:
    """The triangles of a GLB's single primitive (the base GLB: uint32 indices, plain)."""
    if len(glb) < 20 or glb[:4] != b"glTF":
        raise Error("GetMesh(GLB): not a GLB file")
    json_len, json_type = struct.unpack_from("<II", glb, 12)
    doc = json.loads(glb[20:20 + json_len])
    pos = 20 + json_len
    bin_len, _ = struct.unpack_from("<II", glb, pos)
    binary = glb[pos + 8:pos + 8 + bin_len]
    accessor = doc["accessors"][doc["meshes"][0]["primitives"][0]["indices"]]
    view = doc["bufferViews"][accessor["bufferView"]]
    dtype = {5121: "<u1", 5123: "<u2", 5125: "<u4"}[accessor["componentType"]]
    start = view.get("byteOffset", 0) + accessor.get("byteOffset", 0)
    count = int(accessor["count"])
    a = np.frombuffer(binary, dtype=dtype, count=count, offset=start)
    tris: Int64Array = a.astype(np.int64).reshape(-1, 3)
    return tris
