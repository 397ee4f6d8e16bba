"""The 3D leg view: the measured leg and the gait model's "ghost" leg in viser, for an iframe.

viser is not an ASGI app: :class:`LegView` runs a ``viser.ViserServer`` on its own thread and port
and the dashboard embeds :attr:`LegView.url` in an iframe. ``show()`` may be called from any thread
(the server calls it from its asyncio loop at up to ~30 Hz); it never waits for another update.

The viser port streams the session too, so it applies the dashboard's rules (:mod:`gaitscope.server.origin`):
a ``Host`` outside the allowlist is refused (DNS rebinding), and so is a websocket from another origin.
viser 1.1 has no hook for that; it serves with ``websockets.asyncio.server.serve`` and its own
``process_request``, so while the ``ViserServer`` starts, ``serve`` is wrapped to put the guard in
front of viser's hook (:func:`_guarded_serve`). If viser ever starts without going through it, the
view refuses to start rather than run unguarded. With accounts on, the guard also refuses a websocket
without an open login, and registers the one it lets in with the login's
:class:`~gaitscope.sessions.accounts.LoginWatch`: when the login ends (logout, the account disabled, a password
changed) the socket is closed with 1008 and the reason at once.

Scene, in the sagittal plane x (forward) / z (up), y = 0, seen by default from the subject's right::

    /world/ground                      thin wide box tilted by the estimated incline
    /world/leg                         the hip, ``leg_length`` above the ground's origin
    /world/leg/thigh                   frame at the hip; ``segment`` box hangs along its -z
    /world/leg/thigh/shank             frame at the knee (the thigh's distal end)
    /world/leg/thigh/shank/foot        frame at the ankle; its +x points to the toes
    /world/ghost/...                   the same tree, translucent, posed by the gait model
    /world/waiting                     label: "waiting for data" until the first show(), then shown
                                       only when a state has neither leg to draw

Until the first :meth:`LegView.show` the measured leg stands straight in grey under a "waiting for
data" label and the ghost is hidden: the view is never blank (a fresh server after a restart, a review
not yet posed), and the grey and the label say this pose is not data. viser's control panel (the
session, phase, incline and torque) starts minimized so the leg fills the view, even in a phone-sized
iframe where viser shows it as a bottom sheet; the camera looks at the leg from the subject's right.

Angles follow :mod:`gaitscope.sessions.schema` (LocoHub): thigh and shank from vertical, positive when the
distal end is ahead; foot from horizontal, positive toes up; all counter-clockwise seen from the
subject's right. That is a rotation about -y, so a segment at angle ``a`` has
``wxyz = [cos(a/2), 0, -sin(a/2), 0]`` (a rotation about +y by ``-a``), and each child frame holds
its angle relative to its parent (all rotations share the y axis, so they add).

Segment lengths are Winter's fractions of height ``H = leg_length / 0.53`` (as the virtual cohort
uses them, :mod:`gaitscope.sessions.synth.cohort`): thigh 0.245 H, shank 0.246 H, foot 0.152 H, ankle height
0.039 H, so the straight leg's sole touches the ground.

The thigh is neither always sensed nor predicted by the gait model. When a state has no thigh angle,
the thigh is placed consistently with the shank: ``thigh = shank + knee flexion``, with the knee
flexion of Schwartz et al. (2008) at free walking speed at the estimated phase
(:mod:`gaitscope.sessions.synth.normative`). The ghost shares the measured leg's thigh, so both knees coincide and
the ghost's shank and foot differ from the measured ones exactly where the model does.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import math
import threading
from collections.abc import Callable, Iterable, Iterator
from http import HTTPStatus
from typing import TYPE_CHECKING, Any, Final

import numpy as np
import viser
import websockets.asyncio.server
from scipy.interpolate import CubicSpline
from websockets.asyncio.server import ServerConnection
from websockets.http11 import Request

from gaitscope.estimators.gait_model import OUT_FOOT, OUT_SHANK, evaluate
from gaitscope.estimators.pipeline import TrainedModel
from gaitscope.server.origin import LOOPBACK_HOSTS, ProcessRequest, allowed_hosts_for, websockets_guard
from gaitscope.sessions import schema
from gaitscope.sessions.synth.cohort import (
    ANKLE_HEIGHT_FRAC,
    FOOT_FRAC,
    HEEL_BACK_FRAC,
    HIP_HEIGHT_FRAC,
    SHANK_FRAC,
    THIGH_FRAC,
)

if TYPE_CHECKING:
    from gaitscope.sessions.accounts import LoginWatch
from gaitscope.sessions.synth.normative import CLASSES, KNEE, curve_spline, normative

__all__ = ["LegView", "knee_flexion_deg", "quat_y", "segment_angles_for", "status_markdown"]

#: Scene node names.
GROUND: Final = "/world/ground"
LEG: Final = "/world/leg"
GHOST: Final = "/world/ghost"
THIGH, SHANK_NODE, FOOT_NODE = "/thigh", "/thigh/shank", "/thigh/shank/foot"

_GROUND_SIZE = (4.0, 0.8, 0.01)  # m: along x, y and its thickness
_WIDTH_FRAC = 0.045  # segment box width (y and x) as a fraction of height (choice)
_LEG_COLOR = (40, 110, 200)
_WAITING_COLOR = (150, 150, 150)  # the leg before any data: grey, so it never reads as a measurement
_GHOST_COLOR = (255, 140, 0)
_GHOST_OPACITY = 0.35
_GHOST_FATTER = 1.3  # the ghost's boxes are wider so their faces never coincide with the leg's
_DEFAULT_LEG_LENGTH = 0.88  # m, until the first show()
WAITING: Final = "/world/waiting"
WAITING_TEXT: Final = "Waiting for data"
#: The label's words when a state has neither leg to draw (no shank angle, and no finite estimate).
NO_LEG_TEXT: Final = "No leg angles at this moment"
#: The camera: from the subject's right, a little above the knee, close enough that the leg fills a
#: 300 px tall view (45 deg vertical field of view: about 1.6 m of height visible at the leg).
CAMERA_POSITION: Final = (0.15, -1.95, 0.55)
CAMERA_LOOK_AT: Final = (0.15, 0.0, 0.45)
CAMERA_FOV_DEG: Final = 45.0


def quat_y(angle_rad: float) -> np.ndarray:
    """``wxyz`` of a rotation by ``angle_rad`` about +y (right-handed: +x turns towards -z)."""
    return np.array([math.cos(angle_rad / 2), 0.0, math.sin(angle_rad / 2), 0.0])


def _sagittal(angle_deg: float) -> np.ndarray:
    """``wxyz`` of a sagittal angle (counter-clockwise seen from the right, i.e. about -y)."""
    return quat_y(-math.radians(angle_deg))


def _finite(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


@functools.cache
def _knee_spline() -> CubicSpline:
    spline, _ = curve_spline(float(normative().speed[CLASSES.index("free")]))
    return spline


def knee_flexion_deg(phase: float) -> float:
    """Schwartz 2008 knee flexion (deg, flexion positive) at free speed at ``phase`` (cycles)."""
    return float(_knee_spline()(phase % 1.0)[KNEE])


def _measured_angles(state: schema.GaitState) -> dict[str, float | None]:
    """The measured leg's angles (deg); thigh derived from the shank when not sensed."""
    shank = _finite(state.shank_angle_deg)
    thigh = _finite(state.thigh_angle_deg)
    phase = _finite(state.phase)
    if thigh is None and shank is not None and phase is not None:
        thigh = shank + knee_flexion_deg(phase)
    return {"thigh_deg": thigh, "shank_deg": shank, "foot_deg": _finite(state.foot_angle_deg)}


def segment_angles_for(
    state: schema.GaitState, model: TrainedModel | None, leg_length: float
) -> dict[str, float] | None:
    """The ghost leg's segment angles (deg) at the estimated state; pure.

    Foot and shank are the gait model's outputs at ``(phase, stride_length_m / leg_length,
    incline_deg)``; without a model, the state's own ``foot_pred_deg`` and ``shank_pred_deg``. The
    thigh is the measured leg's (sensed, or ``measured shank + knee flexion(phase)``), or the ghost's
    ``shank + knee flexion(phase)`` when the state has no shank angle either.

    Returns:
        ``{"thigh_deg", "shank_deg", "foot_deg"}``, or None when the estimate is not finite.
    """
    if not leg_length > 0:
        raise ValueError(f"leg length must be positive, got {leg_length}")
    p, s, r = _finite(state.phase), _finite(state.stride_length_m), _finite(state.incline_deg)
    if p is None or s is None or r is None:
        return None
    if model is None:
        foot, shank = _finite(state.foot_pred_deg), _finite(state.shank_pred_deg)
        if foot is None or shank is None:
            return None
    else:
        y = evaluate(model.coef, np.array([p]), np.array([s / leg_length]), np.array([r]))[0]
        foot, shank = float(y[OUT_FOOT]), float(y[OUT_SHANK])
    thigh = _measured_angles(state)["thigh_deg"]
    if thigh is None:
        thigh = shank + knee_flexion_deg(p)
    return {"thigh_deg": thigh, "shank_deg": shank, "foot_deg": foot}


def status_markdown(state: schema.GaitState | None, session_id: int | None) -> str:
    """The panel's read-only text: session id, phase, incline and torque."""
    rows = [("session", "-" if session_id is None else str(session_id))]
    if state is None:
        rows += [("phase", "-"), ("incline", "-"), ("torque", "-")]
    else:
        rows += [
            ("phase", "not estimated" if state.phase is None else f"{state.phase:.2f}"),
            ("incline", "not estimated" if state.incline_deg is None else f"{state.incline_deg:+.1f} deg"),
            ("torque", f"{state.torque_Nm:.1f} N m"),
        ]
    return "  \n".join(f"**{k}** {v}" for k, v in rows)  # two spaces: a markdown line break


class _Leg:
    """Handles of one leg tree (``/world/leg`` or ``/world/ghost``)."""

    def __init__(self, scene: viser.SceneApi, root: str, ghost: bool) -> None:
        color, opacity = (_GHOST_COLOR, _GHOST_OPACITY) if ghost else (_LEG_COLOR, None)
        self.fat = _GHOST_FATTER if ghost else 1.0
        # The ghost is hidden until the first show() (a default prediction would look like data); the
        # measured leg stands in grey (see LegView.waiting).
        self.root = scene.add_frame(root, show_axes=False, visible=not ghost)
        self.thigh = scene.add_frame(root + THIGH, show_axes=False)
        self.shank = scene.add_frame(root + SHANK_NODE, show_axes=False)
        self.foot = scene.add_frame(root + FOOT_NODE, show_axes=False)
        self.boxes = [
            scene.add_box(f"{root}{node}/segment", color=color, opacity=opacity, cast_shadow=False)
            for node in (THIGH, SHANK_NODE, FOOT_NODE)
        ]

    def resize(self, leg_length: float) -> None:
        """Segment lengths and positions for a leg of ``leg_length`` (hip to floor, m)."""
        h = leg_length / HIP_HEIGHT_FRAC
        thigh, shank, foot, ankle = THIGH_FRAC * h, SHANK_FRAC * h, FOOT_FRAC * h, ANKLE_HEIGHT_FRAC * h
        w = _WIDTH_FRAC * h * self.fat
        self.root.position = (0.0, 0.0, leg_length)
        self.shank.position = (0.0, 0.0, -thigh)
        self.foot.position = (0.0, 0.0, -shank)
        b_thigh, b_shank, b_foot = self.boxes
        b_thigh.dimensions, b_thigh.position = (w, w, thigh), (0.0, 0.0, -thigh / 2)
        b_shank.dimensions, b_shank.position = (w, w, shank), (0.0, 0.0, -shank / 2)
        b_foot.dimensions = (foot, w, ankle * self.fat)
        b_foot.position = (foot * (0.5 - HEEL_BACK_FRAC), 0.0, -ankle / 2)

    def pose(self, thigh: float, shank: float, foot: float | None) -> None:
        """Global sagittal angles (deg); ``foot=None`` hides the foot and leaves its pose."""
        self.thigh.wxyz = _sagittal(thigh)
        self.shank.wxyz = _sagittal(shank - thigh)
        if foot is not None:
            self.foot.wxyz = _sagittal(foot - shank)
        self.boxes[2].visible = foot is not None

    def paint(self, color: tuple[int, int, int]) -> None:
        for box in self.boxes:
            box.color = color


_serve_lock = threading.Lock()  # one guarded start at a time: the wrapper is process-wide while it lasts


@contextlib.contextmanager
def _guarded_serve(
    allowed_hosts: Iterable[str], logged_in: LoggedIn | None = None, watch: LoginWatch | None = None
) -> Iterator[list[int]]:
    """While open, ``websockets.asyncio.server.serve`` runs :func:`gaitscope.server.origin.websockets_guard`
    before the caller's own ``process_request``; with ``logged_in`` (accounts on), a websocket whose
    ``Cookie`` header carries no open login is refused too (401): the dashboard's login cookie is sent to
    the leg view's port as well, cookies being per host, not per port. With ``watch`` too, a websocket let
    in is closed (1008) when its login ends.

    Yields a list that gets an entry per guarded ``serve`` call, to check that the guard is in place.
    """
    original = websockets.asyncio.server.serve
    allowed = list(allowed_hosts)
    installed: list[int] = []

    def serve(*args: Any, process_request: ProcessRequest | None = None, **kwargs: Any) -> Any:
        installed.append(1)
        then = process_request if logged_in is None else _login_guard(logged_in, process_request, watch)
        return original(*args, process_request=websockets_guard(allowed, then=then), **kwargs)

    with _serve_lock:
        websockets.asyncio.server.serve = serve  # type: ignore[misc, assignment]
        try:
            yield installed
        finally:
            websockets.asyncio.server.serve = original  # type: ignore[misc]


#: Whether a ``Cookie`` header holds an open login: falsy if not; the login's id (an int), or True.
LoggedIn = Callable[[str], int | bool | None]


def _login_guard(logged_in: LoggedIn, then: ProcessRequest | None, watch: LoginWatch | None) -> ProcessRequest:
    def process_request(connection: ServerConnection, request: Request) -> Any:
        upgrade = any("websocket" in u.lower() for u in request.headers.get_all("Upgrade"))
        if not upgrade:
            return None if then is None else then(connection, request)
        login = logged_in("; ".join(request.headers.get_all("Cookie")))
        if not login:
            return connection.respond(HTTPStatus.UNAUTHORIZED, "log in to the dashboard first\n")
        if watch is not None and not isinstance(login, bool):
            _close_when_login_ends(connection, login, watch)
        return None if then is None else then(connection, request)

    return process_request


def _close_when_login_ends(connection: ServerConnection, login_id: int, watch: LoginWatch) -> None:
    """Close ``connection`` (1008, the reason) when login ``login_id`` ends; stop watching when it closes.
    Called on viser's event loop (in the handshake); the watch calls back from any thread."""
    loop = asyncio.get_running_loop()

    def close(reason: str) -> None:
        asyncio.run_coroutine_threadsafe(connection.close(1008, reason[:120]), loop)

    unwatch = watch.watch(login_id, close)

    async def unwatch_when_closed() -> None:
        try:
            await connection.wait_closed()
        finally:
            unwatch()

    task = loop.create_task(unwatch_when_closed())
    _closing_tasks.add(task)  # a reference until it is done (the loop keeps only weak ones)
    task.add_done_callback(_closing_tasks.discard)


_closing_tasks: set[asyncio.Task[None]] = set()


class LegView:
    """A viser server showing the measured leg against the gait model's prediction.

    Args:
        host: interface to bind.
        port: port to ask for; viser takes the next free one if it is busy (0: any free port).
            :attr:`port` is the one it got.
        model: the gait model that poses the ghost; None uses the states' ``*_pred_deg``.
        allowed_hosts: the names the view may be reached at (``Settings.allowed_hosts``); default
            the loopback names and ``host``.
        logged_in: with accounts on, tells whether a request's ``Cookie`` header holds an open login (its
            id, or True); the view's websocket is refused without one. None: accounts off.
        watch: with ``logged_in``, the logins' watch: a websocket whose login ends is closed (1008).

    Raises:
        RuntimeError: viser started without the host guard (a viser version that serves otherwise).
    """

    def __init__(
        self,
        host: str = "127.0.0.1",
        port: int = 8081,
        model: TrainedModel | None = None,
        allowed_hosts: Iterable[str] | None = None,
        logged_in: LoggedIn | None = None,
        watch: LoginWatch | None = None,
    ) -> None:
        self._host = host
        self._model = model
        self._lock = threading.Lock()  # held by one update (or close) at a time
        self._closed = False
        self._leg_length = _DEFAULT_LEG_LENGTH
        self.allowed_hosts = allowed_hosts_for(host, LOOPBACK_HOSTS if allowed_hosts is None else allowed_hosts)
        with _guarded_serve(self.allowed_hosts, logged_in, watch) as installed:
            self.server = viser.ViserServer(host=host, port=port, label="gaitscope leg", verbose=False)
        try:
            if not installed:
                raise RuntimeError("viser did not start through websockets.asyncio.server.serve: no host guard")
            self._build()
        except BaseException:
            self.server.stop()
            raise

    def _build(self) -> None:
        server = self.server
        server.initial_camera.position = CAMERA_POSITION
        server.initial_camera.look_at = CAMERA_LOOK_AT
        server.initial_camera.fov = math.radians(CAMERA_FOV_DEG)
        scene = server.scene
        self._ground = scene.add_box(GROUND, color=(170, 170, 170), dimensions=_GROUND_SIZE, cast_shadow=False)
        self._leg = _Leg(scene, LEG, ghost=False)
        self._ghost = _Leg(scene, GHOST, ghost=True)
        self._resize(_DEFAULT_LEG_LENGTH)
        self._set_incline(0.0)
        self._leg.pose(0.0, 0.0, 0.0)
        self._leg.paint(_WAITING_COLOR)
        self._waiting = True
        self._label = scene.add_label(
            WAITING, WAITING_TEXT, position=(0.0, 0.0, _DEFAULT_LEG_LENGTH + 0.15), anchor="bottom-center"
        )
        gui = server.gui
        # No logo and no share button: the share button offers a public tunnel, which a clinic's
        # offline dashboard must not suggest. The panel starts minimized (replayed to every client).
        gui.configure_theme(show_logo=False, show_share_button=False)
        gui.main_panel.minimize()
        gui.add_markdown("Leg: measured (blue) and gait model (translucent orange)")
        # Markdown rather than disabled text inputs: read-only by nature, one message per update,
        # and viser 1.1's GuiInputHandle.value setter is invisible to mypy (a method sits between
        # the getter and the setter).
        self._status = gui.add_markdown(status_markdown(None, None))

    @property
    def port(self) -> int:
        """The port viser actually listens on."""
        return self.server.get_port()

    @property
    def url(self) -> str:
        """``http://host:port/`` for the iframe (a wildcard host is reported as 127.0.0.1)."""
        host = {"": "127.0.0.1", "0.0.0.0": "127.0.0.1", "::": "::1"}.get(self._host, self._host)
        if ":" in host:
            host = f"[{host}]"
        return f"http://{host}:{self.port}/"

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def waiting(self) -> bool:
        """True until the first :meth:`show`: the leg stands in grey under a "waiting for data" label."""
        return self._waiting

    def set_model(self, model: TrainedModel) -> None:
        """Pose the ghost with ``model`` from the next :meth:`show` on."""
        self._model = model

    def show(self, state: schema.GaitState, leg_length_m: float, session_id: int | None = None) -> None:
        """Pose both legs, the ground and the panel at ``state``.

        Returns at once, doing nothing, if another thread is updating the view or it is closed.
        A leg whose shank angle is unknown (or not finite) is hidden; so is a foot without an angle.

        Args:
            state: the estimate and the measured segment angles.
            leg_length_m: the walker's leg length (hip to floor), m.
            session_id: shown in the panel.
        """
        if not (math.isfinite(leg_length_m) and leg_length_m > 0):
            raise ValueError(f"leg length must be a positive number of metres, got {leg_length_m}")
        if not self._lock.acquire(blocking=False):
            return
        try:
            if self._closed:
                return
            measured = _measured_angles(state)
            ghost = segment_angles_for(state, self._model, leg_length_m)
            with self.server.atomic():
                if self._waiting:
                    self._waiting = False
                    self._leg.paint(_LEG_COLOR)
                if leg_length_m != self._leg_length:
                    self._resize(leg_length_m)
                thigh, shank = measured["thigh_deg"], measured["shank_deg"]
                self._leg.root.visible = thigh is not None and shank is not None
                if thigh is not None and shank is not None:
                    self._leg.pose(thigh, shank, measured["foot_deg"])
                self._ghost.root.visible = ghost is not None
                if ghost is not None:
                    self._ghost.pose(ghost["thigh_deg"], ghost["shank_deg"], ghost["foot_deg"])
                # Never a bare floor: with neither leg to draw, the label says why.
                no_leg = ghost is None and (thigh is None or shank is None)
                if no_leg:
                    self._label.text = NO_LEG_TEXT
                self._label.visible = no_leg
                incline = _finite(state.incline_deg)
                if incline is not None:
                    self._set_incline(incline)
                self._status.content = status_markdown(state, session_id)
        finally:
            self._lock.release()

    def _resize(self, leg_length: float) -> None:
        self._leg.resize(leg_length)
        self._ghost.resize(leg_length)
        self._leg_length = leg_length

    def _set_incline(self, incline_deg: float) -> None:
        """Tilt the ground by ``incline_deg`` (uphill positive) about the y axis through the origin."""
        q = _sagittal(incline_deg)
        a = math.radians(incline_deg)
        half = _GROUND_SIZE[2] / 2  # top face through the origin: centre half a thickness below
        self._ground.wxyz = q
        self._ground.position = (half * math.sin(a), 0.0, -half * math.cos(a))

    def close(self) -> None:
        """Stop the viser server and its thread; waits for an update in flight. Idempotent."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        self.server.stop()
