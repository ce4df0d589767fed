"""The operator station's web server (Starlette): the page, its JSON API and the live stream.

Routes
- ``GET /`` the page (``static/index.html``, plain JavaScript and canvas plots: no build step);
- ``GET /api/state`` the live snapshot; ``GET /api/events`` the same as Server-Sent Events, a
  message whenever it changed, at most every ``PUSH_INTERVAL_S`` (4 per second);
- ``POST /api/start`` ``{"operator", "sockets": {"1": serial, ...}, "seed"}``: checked (a 400
  message in the operator's words naming the bad value; the spec chosen by the serials,
  ``products``), then the batch in a thread: the "mount the units" prompt, the station opened
  with its fixture, the spec's batch acceptance, one report per unit.  Every run records its
  seed: the operator's, else the station's, else one drawn from the system's random source;
- ``POST /api/prompt`` ``{"answer": "continue"|"abort"}``; ``POST /api/abort``: Abort — the
  runner's interrupt path leaves the station safe, every record says why it stopped;
- ``GET /api/history?serial=&verdict=&date=`` stored runs, newest first, each with its
  procedure, its result (an acceptance's verdict, any other run's own status) and its seed;
  ``GET /reports/<run>/...`` reports;
- ``GET /api/doctor`` ``bench doctor``'s table (refused while a batch runs; an engineer's);
- ``GET /api/whoami`` the login (``{}`` when the station needs none).

Served beyond loopback, every route needs a login (``bench.app.operator.auth``).
"""

from __future__ import annotations

import asyncio
import json
import secrets
import threading
from collections.abc import AsyncIterator
from dataclasses import asdict
from pathlib import Path
from typing import Any

from starlette.applications import Starlette
from starlette.middleware import Middleware
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response, StreamingResponse
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from bench.app.batch import MAX_SOCKETS, check_socket, run_batch
from bench.app.health import diagnose
from bench.app.labels import SEED_RANGE
from bench.app.operator.auth import LoginRequired, Users
from bench.app.operator.live import AbortableClock, LiveBatch, LiveStore
from bench.app.operator.products import Products
from bench.app.reports.acceptance_report import acceptance_document
from bench.app.reports.parallel import start_report_server
from bench.app.verdict import measurements_of, verdict_of
from bench.app.wording import procedure_text
from bench.core.operator import OperatorAbort
from procedures.batch_acceptance import BatchAcceptance

STATIC = Path(__file__).resolve().parent / "static"
PUSH_INTERVAL_S = 0.25
MAX_OPERATOR_CHARS = 64
#: a seed drawn for a batch given none: 32 bits from the system's random source — ten digits an
#: operator can read off the page and type back to replay the run
DRAWN_SEED_BITS = 32


def batch_seed(given: Any, station_seed: int | None, simulation: dict[str, Any] | None) -> int | None:
    """The seed of a batch started from the page: the operator's (``given``: a whole number or
    its digits; empty or None for none), else the station's (``--seed``, else its
    ``[simulation] seed``), else drawn from the system's random source.  None on a real
    station: it has no simulated world to seed.  ValueError in the operator's words otherwise."""
    if isinstance(given, str):
        given = given.strip()
        if given.isdigit():
            given = int(given)
    if given is None or given == "":
        if simulation is None:
            return None
        if station_seed is not None:
            return station_seed
        if simulation.get("seed") is not None:
            return int(simulation["seed"])
        return secrets.randbits(DRAWN_SEED_BITS)
    if simulation is None:
        raise ValueError(f"Seed {given!r}: this is a real station, it takes no seed — leave Seed empty.")
    if isinstance(given, bool) or not isinstance(given, int) or not SEED_RANGE[0] <= given < SEED_RANGE[1]:
        raise ValueError(f"Seed {given!r} must be a whole number from 0 to {SEED_RANGE[1] - 1}, or "
                         "left empty (a new one is drawn).")
    return given


class OperatorStation:
    """One station's server state: its config, store, reports folder and the live batch."""

    def __init__(self, config: Any, store_path: str | Path, report_root: str | Path, *,
                 seed: int | None = None, spec_path: str | None = None,
                 labels: dict[str, str] | None = None) -> None:
        self.config = config
        self.live = LiveBatch()
        self.store = LiveStore(store_path, self.live)
        self.report_root = Path(report_root)
        self.report_root.mkdir(parents=True, exist_ok=True)
        self.seed, self.spec_path = seed, spec_path
        self.products = Products(spec_path)  # read now: a broken spec stops the start
        self.labels = dict(labels or {})
        self.thread: threading.Thread | None = None
        self.last_station: Any = None  # the station the last batch opened (tests read its sim)
        start_report_server()  # the report workers' imports, once, before the first batch

    # -- starting a batch ------------------------------------------------------------------
    @property
    def info(self) -> dict[str, Any]:
        """What the page shows of the station: its name and whether it takes a seed."""
        return {"name": self.config.name, "seeded": self.config.simulation is not None}

    def check_start(self, body: Any) -> tuple[str, dict[int, str], Any, int | None]:
        """The operator's form, checked: (operator, sockets, spec, seed); ValueError naming
        the problem in the operator's words."""
        if not isinstance(body, dict):
            raise ValueError("the request must be a JSON object {operator, sockets}")
        operator = body.get("operator")
        if not isinstance(operator, str) or not operator.strip():
            raise ValueError("operator name is required")
        operator = operator.strip()
        if len(operator) > MAX_OPERATOR_CHARS or not operator.isprintable():
            raise ValueError(f"operator name must be 1..{MAX_OPERATOR_CHARS} printable characters")
        given = body.get("sockets")
        if not isinstance(given, dict):
            raise ValueError("sockets must be an object {socket: serial}")
        sockets: dict[int, str] = {}
        for key, serial in given.items():
            serial = serial.strip() if isinstance(serial, str) else serial
            if serial == "" or serial is None:
                continue  # an empty socket
            sockets.update(check_socket(key, serial, sockets))
        if not sockets:
            raise ValueError(f"scan or type at least one serial (sockets 1..{MAX_SOCKETS})")
        spec = self.products.spec_for(sockets)
        return operator, sockets, spec, batch_seed(body.get("seed"), self.seed, self.config.simulation)

    def start(self, operator: str, sockets: dict[int, str], spec: Any, seed: int | None) -> None:
        steps = [(s.name, s.duration_s()) for s in BatchAcceptance(spec).steps]
        self.live.begin(operator, spec.model, sockets, steps, seed=seed,
                        labels={m.name: m.label for m in spec.measurements},
                        wall_per_planned_s=None if self.config.simulated else 1.0)
        self.thread = threading.Thread(target=self._run, args=(sockets, spec, seed), daemon=True,
                                       name="operator-batch")
        self.thread.start()

    def _run(self, sockets: dict[int, str], spec: Any, seed: int | None) -> None:
        live = self.live
        listed = ", ".join(str(n) for n in sockets)
        if not live.ask(f"Mount the units in socket{'s' if len(sockets) > 1 else ''} {listed}, "
                        "connect their cables and close the fixture cover."):
            live.finish("aborted", "aborted by the operator before the start")
            return
        live.running()

        def attach(station: Any) -> None:
            station.clock = AbortableClock(station.clock, live)
            self.last_station = station

        labels = {**self.labels, "station_id": self.labels.get("station_id", f"operator:{self.config.name}"),
                  "operator": live.operator}
        try:
            result = run_batch(self.config, sockets, spec, self.store, seed=seed,
                               report_root=self.report_root, labels=labels, progress=live.progress,
                               on_socket=live.socket_ended, on_station=attach, operator=live)
        except OperatorAbort as exc:
            self._verdicts_of_stored()
            live.finish("aborted", f"{exc}: station left safe")
            return
        except Exception as exc:  # the station could not be opened, a report failed...
            self._verdicts_of_stored()
            live.finish("aborted", f"The batch stopped: {exc}. The station is left safe; tell the "
                        "test engineer (Station health checks every instrument).")
            return
        for n, doc in result.documents.items():
            report = f"/reports/{doc['run_id']}/acceptance_report.html" if doc.get("report") else None
            live.verdict(n, doc["verdict"], report)
        live.finish("done")

    def _verdicts_of_stored(self) -> None:
        for view in list(self.live.sockets.values()):
            if view.run_id is None:
                continue
            try:
                doc = acceptance_document(self.store, view.run_id)
            except Exception:  # a run that was never finished: nothing to show
                continue
            self.live.socket_ended(view.socket, doc["status"], doc.get("reason"))
            self.live.verdict(view.socket, doc["verdict"], None)

    # -- history and health ----------------------------------------------------------------
    def history(self, serial: str = "", verdict: str = "", date: str = "") -> list[dict[str, Any]]:
        """Stored runs, newest first: an acceptance with its verdict (PASS, PASS (marginal),
        FAIL, ABORTED, RUNNING), any other run (``bench run startup``, ...) with its own status
        and no verdict — a ``verdict`` filter matches acceptances only."""
        rows = []
        for info in self.store.list_runs(limit=500):
            if serial and serial.lower() not in (info.unit_serial or "").lower():
                continue
            if date and not info.started_utc.startswith(date):
                continue
            acceptance = info.procedure == "acceptance"
            judged = None
            if acceptance:
                judged = ("RUNNING" if info.status == "running"
                          else verdict_of(info.status, measurements_of(info.results)))
            if verdict and not (judged and judged.upper().startswith(verdict.upper())):
                continue
            report = self.report_root / info.id / "acceptance_report.html"
            rows.append({"run_id": info.id, "serial": info.unit_serial, "procedure": info.procedure,
                         "procedure_text": procedure_text(info.procedure, info.parameters),
                         "socket": info.labels.get("socket"), "started_utc": info.started_utc,
                         "status": info.status, "verdict": judged, "result": judged or info.status,
                         "reason": info.reason, "seed": info.seed,
                         "seed_text": "" if info.seed is None else str(info.seed),
                         "report": f"/reports/{info.id}/acceptance_report.html" if report.is_file() else None})
        return rows

    def doctor(self) -> list[dict[str, Any]]:
        return [asdict(h) for h in diagnose(self.config)]


def create_app(station: OperatorStation, users: Users | None = None) -> Starlette:
    """The Starlette application of ``station``; with ``users`` every route needs a login
    (``bench.app.operator.auth``) and a batch records its login as the operator."""

    async def index(request: Request) -> Response:
        return FileResponse(STATIC / "index.html")

    def snapshot() -> dict[str, Any]:
        return {**station.live.snapshot(), "station": station.info}

    async def state(request: Request) -> Response:
        return JSONResponse(snapshot())

    async def events(request: Request) -> Response:
        async def stream() -> AsyncIterator[str]:
            seen = -1
            while True:
                if await request.is_disconnected():
                    return
                snap = snapshot()
                if snap["version"] != seen or snap["state"] == "running":
                    seen = snap["version"]
                    yield f"data: {json.dumps(snap, allow_nan=False, default=str)}\n\n"
                await asyncio.sleep(PUSH_INTERVAL_S)
        return StreamingResponse(stream(), media_type="text/event-stream",
                                 headers={"Cache-Control": "no-cache"})

    async def start(request: Request) -> Response:
        if station.live.busy:
            return JSONResponse({"error": "a batch is running: wait for it or abort it"}, status_code=409)
        try:
            body = await request.json()
        except ValueError:
            return JSONResponse({"error": "the request is not JSON"}, status_code=400)
        user = request.scope.get("bench_user")
        if user is not None and isinstance(body, dict):
            body = {**body, "operator": user.name}  # who logged in is who runs it
        try:
            operator, sockets, spec, seed = await asyncio.to_thread(station.check_start, body)
        except (ValueError, LookupError) as exc:
            return JSONResponse({"error": str(exc)}, status_code=400)
        station.start(operator, sockets, spec, seed)
        return JSONResponse({"started": True, "spec": spec.model, "seed": seed,
                             "sockets": {str(n): s for n, s in sockets.items()}})

    async def prompt(request: Request) -> Response:
        try:
            answer = (await request.json()).get("answer")
        except (ValueError, AttributeError):
            answer = None
        if answer not in ("continue", "abort"):
            return JSONResponse({"error": "answer must be 'continue' or 'abort'"}, status_code=400)
        if not station.live.answer(answer == "continue"):
            return JSONResponse({"error": "no prompt is open"}, status_code=409)
        return JSONResponse({"answered": answer})

    async def abort(request: Request) -> Response:
        if not station.live.request_abort():
            return JSONResponse({"error": "nothing is running"}, status_code=409)
        return JSONResponse({"aborting": True})

    async def whoami(request: Request) -> Response:
        user = request.scope.get("bench_user")
        return JSONResponse({} if user is None else {"user": user.name, "role": user.role})

    async def history(request: Request) -> Response:
        q = request.query_params
        rows = await asyncio.to_thread(station.history, q.get("serial", ""), q.get("verdict", ""),
                                       q.get("date", ""))
        return JSONResponse({"runs": rows})

    async def doctor(request: Request) -> Response:
        if station.live.busy:
            return JSONResponse({"error": "the station is busy with a batch"}, status_code=409)
        try:
            rows = await asyncio.to_thread(station.doctor)
        except ValueError as exc:
            return JSONResponse({"error": str(exc)}, status_code=400)
        return JSONResponse({"instruments": rows})

    routes = [
        Route("/", index), Route("/api/state", state), Route("/api/events", events),
        Route("/api/start", start, methods=["POST"]), Route("/api/prompt", prompt, methods=["POST"]),
        Route("/api/abort", abort, methods=["POST"]), Route("/api/history", history),
        Route("/api/doctor", doctor), Route("/api/whoami", whoami),
        Mount("/static", StaticFiles(directory=STATIC), name="static"),
        Mount("/reports", StaticFiles(directory=station.report_root, check_dir=False), name="reports"),
    ]
    middleware = [] if users is None else [Middleware(LoginRequired, users=users)]
    return Starlette(routes=routes, middleware=middleware)


__all__ = ["OperatorStation", "create_app", "batch_seed", "PUSH_INTERVAL_S", "DRAWN_SEED_BITS"]
