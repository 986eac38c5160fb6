"""The closed-loop road: a straight three-lane highway, built with SUMO's own ``netconvert``.

Geometry (SUMO network coordinates, metres)::

    y
    ^   lane 2 (left)    centre y = -w/2          x: 0 ............ length
    |   lane 1 (middle)  centre y = -3w/2
    |   lane 0 (right)   centre y = -5w/2         driving direction +x

The edge ``hw`` runs from ``(0, 0)`` to ``(length, 0)`` with ``lanes`` lanes of width ``w``
(3.75 m, the SPEC §8 lane offset ``y_f - y_0 = 5.75`` is about 1.5 of these); SUMO spreads the
lanes to the right of the edge line, so lane ``k`` has its centre at
``y_k = -(lanes - k - 1/2)·w``.  The lane centres are read back from the built network
(:func:`lane_centres`) rather than assumed.

The network is built once per parameter set into a cache folder (``$IAMP_SIM_CACHE`` or the
system temporary folder) and reused; the file name carries a hash of everything that defines
it, and it is written atomically so that concurrent workers cannot see half a file.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from iamp.core.errors import IampError, MissingDependencyError

INSTALL_HINT = "pip install 'iamp[sim]'"


def require_sumo() -> None:
    """Raise :class:`MissingDependencyError` unless ``libsumo`` and ``sumolib`` import."""
    try:
        import libsumo  # noqa: F401
        import sumolib  # noqa: F401
    except ImportError as exc:
        raise MissingDependencyError(
            f"the closed-loop simulation needs Eclipse SUMO ({exc.name} is missing): {INSTALL_HINT}") from None


def find_binary(name: str) -> str:
    """Path of the SUMO tool ``name`` (``netconvert``, ``sumo``).

    Looks in the ``eclipse-sumo`` wheel first (``sumo.SUMO_HOME/bin``), then asks
    :func:`sumolib.checkBinary` (``$SUMO_HOME``, ``$<NAME>_BINARY``, ``PATH``).
    """
    try:
        import sumo  # the eclipse-sumo wheel (typed as Any: pyproject mypy overrides)

        cand = Path(sumo.SUMO_HOME) / "bin" / name
        if cand.is_file() and os.access(cand, os.X_OK):
            return str(cand)
    except ImportError:
        pass
    try:
        import sumolib
    except ImportError:
        raise MissingDependencyError(f"SUMO's {name} is not installed: {INSTALL_HINT}") from None
    found = str(sumolib.checkBinary(name))
    if os.path.isabs(found) and os.access(found, os.X_OK):
        return found
    which = shutil.which(found)
    if which is None:
        raise MissingDependencyError(f"SUMO's {name} is not installed: {INSTALL_HINT}")
    return which


@dataclass(frozen=True)
class Highway:
    """A straight highway along ``+x``.

    Parameters
    ----------
    length : float
        Road length [m].
    lanes : int
        Number of lanes (lane 0 is the rightmost).
    lane_width : float
        Lane width ``w`` [m].
    speed_limit : float
        [m/s] (33.33 = 120 km/h).
    """

    length: float = 3000.0
    lanes: int = 3
    lane_width: float = 3.75
    speed_limit: float = 33.33
    edge: str = "hw"
    #: ``x`` where the rightmost lane ends (a lane drop; ``None``: no drop).  Upstream of it the
    #: road is edge ``hw1``, downstream ``hw2``; both have ``lanes`` lanes of the same geometry
    #: (so the junction between them has no length: with ``--no-internal-links`` a junction of
    #: 8 m, which netconvert makes where the lane count changes, made every vehicle jump 8 m),
    #: but lane 0 of ``hw2`` is closed (``disallow="all"``) and lane 0 of ``hw1`` has no
    #: successor.
    drop_x: float | None = None
    #: ``x`` where an on-ramp joins (``None``: no ramp).  Upstream of it (edge ``hw0``) lane 0 is
    #: the ramp with speed limit ``ramp_speed``, separated from lane 1 (no vehicle class may
    #: change between them: ``changeLeft``/``changeRight`` only for ``custom1``, which nobody
    #: is); from ``ramp_x`` to ``drop_x`` it is the acceleration lane.
    ramp_x: float | None = None
    ramp_speed: float = 16.67

    def segments(self) -> list[tuple[str, float, float, int]]:
        """The edges ``(id, x_start, x_end, lanes)`` along the road, upstream first."""
        if self.drop_x is None:
            return [(self.edge, 0.0, self.length, self.lanes)]
        out: list[tuple[str, float, float, int]] = []
        x = 0.0
        if self.ramp_x is not None:
            out.append(("hw0", 0.0, self.ramp_x, self.lanes))
            x = self.ramp_x
        out.append(("hw1", x, self.drop_x, self.lanes))
        out.append(("hw2", self.drop_x, self.length, self.lanes - 1))
        return out

    def edge_at(self, x: float) -> tuple[str, float, int]:
        """``(edge id, its start x, its first open lane)`` of the edge containing ``x`` (lane
        indices are the same on every edge)."""
        segs = self.segments()
        for eid, x0, x1, n in segs:
            if x < x1:
                return eid, x0, self.lanes - n
        eid, x0, _, n = segs[-1]
        return eid, x0, self.lanes - n

    def route(self, x: float) -> str:
        """Edge ids from the edge containing ``x`` to the end."""
        ids = [eid for eid, _, x1, _ in self.segments() if x < x1]
        return " ".join(ids or [self.segments()[-1][0]])

    def lane_centre(self, lane: int) -> float:
        """``y_k = -(lanes - k - 1/2)·w`` (SUMO spreads lanes to the right of the edge line)."""
        return -(self.lanes - lane - 0.5) * self.lane_width

    def lane_of(self, y: float) -> int:
        """Index of the lane whose band contains ``y`` (clipped to the road)."""
        k = int(self.lanes - 1 - (-y) // self.lane_width)
        return min(max(k, 0), self.lanes - 1)

    def lanes_of(self, y: np.ndarray) -> np.ndarray:
        """:meth:`lane_of` of every element of ``y`` (finite), as one array operation: numpy's floor
        division and truncation are Python's, so the indices are the same.

        Parameters
        ----------
        y : numpy.ndarray
            Lateral positions [m].

        Returns
        -------
        numpy.ndarray
            The lane index of each position (``int``), the shape of ``y``.
        """
        k = (self.lanes - 1 - np.floor_divide(-np.asarray(y, dtype=float), self.lane_width)).astype(np.int64)
        return np.asarray(np.minimum(np.maximum(k, 0), self.lanes - 1), dtype=int)

    def lane_centres_of(self, y: np.ndarray) -> np.ndarray:
        """``lane_centre(lane_of(y))`` of every element of ``y`` (finite), as one array operation
        (:meth:`lanes_of`; the same floats).

        Parameters
        ----------
        y : numpy.ndarray
            Lateral positions [m].

        Returns
        -------
        numpy.ndarray
            The centre of each position's lane [m], the shape of ``y``.
        """
        lane = self.lanes_of(y)
        return np.asarray(-(self.lanes - lane - 0.5) * self.lane_width, dtype=float)

    def key(self) -> str:
        text = (f"{self.length:.3f}|{self.lanes}|{self.lane_width:.3f}|{self.speed_limit:.3f}|{self.edge}|"
                f"{self.drop_x}|{self.ramp_x}|{self.ramp_speed:.3f}|closed-lane")
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def nodes_xml(self) -> str:
        segs = self.segments()
        xs = [x0 for _, x0, _, _ in segs] + [segs[-1][2]]
        lines = ['<nodes>']
        for k, x in enumerate(xs):
            lines.append(f'    <node id="n{k}" x="{x:.3f}" y="0.0" type="priority"/>')
        return "\n".join(lines + ['</nodes>']) + "\n"

    def edges_xml(self) -> str:
        lines = ['<edges>']
        for k, (eid, _, _, n) in enumerate(self.segments()):
            inner = ([f'        <lane index="0" speed="{self.ramp_speed:.3f}" changeLeft="custom1"/>',
                      '        <lane index="1" changeRight="custom1"/>'] if eid == "hw0" else [])
            inner += [f'        <lane index="{j}" disallow="all"/>' for j in range(self.lanes - n)]
            lines.append(f'    <edge id="{eid}" from="n{k}" to="n{k + 1}" numLanes="{self.lanes}" '
                         f'speed="{self.speed_limit:.3f}" width="{self.lane_width:.3f}" priority="1"'
                         + (">\n" + "\n".join(inner) + "\n    </edge>" if inner else "/>"))
        return "\n".join(lines + ['</edges>']) + "\n"

    def connections_xml(self) -> str:
        """Lane-to-lane connections: straight on; the dropped lane 0 has none."""
        segs = self.segments()
        lines = ['<connections>']
        for (a, _, _, _), (b, _, _, nb) in zip(segs, segs[1:]):
            for k in range(self.lanes - nb, self.lanes):
                lines.append(f'    <connection from="{a}" to="{b}" fromLane="{k}" toLane="{k}"/>')
        return "\n".join(lines + ['</connections>']) + "\n"


def cache_dir() -> Path:
    """``$IAMP_SIM_CACHE`` or ``<tmp>/iamp-sim-cache``."""
    root = os.environ.get("IAMP_SIM_CACHE") or os.path.join(tempfile.gettempdir(), "iamp-sim-cache")
    path = Path(root)
    path.mkdir(parents=True, exist_ok=True)
    return path


def build_network(highway: Highway | None = None, folder: Path | None = None) -> Path:
    """Build (or reuse) the ``.net.xml`` of ``highway`` with ``netconvert``; returns its path.

    Options: ``--offset.disable-normalization`` keeps the given coordinates,
    ``--no-internal-links`` and ``--no-turnarounds`` leave one plain edge.
    """
    hw = highway or Highway()
    folder = folder or cache_dir()
    net = folder / f"highway-{hw.key()}.net.xml"
    if net.is_file():
        return net
    netconvert = find_binary("netconvert")
    with tempfile.TemporaryDirectory(prefix="iamp-net-", dir=str(folder)) as tmp:
        work = Path(tmp)
        (work / "hw.nod.xml").write_text(hw.nodes_xml())
        (work / "hw.edg.xml").write_text(hw.edges_xml())
        (work / "hw.con.xml").write_text(hw.connections_xml())
        cmd = [netconvert, "-n", "hw.nod.xml", "-e", "hw.edg.xml", "-x", "hw.con.xml", "-o", "hw.net.xml",
               "--offset.disable-normalization", "--no-internal-links", "--no-turnarounds", "--no-warnings"]
        proc = subprocess.run(cmd, cwd=work, capture_output=True, text=True, check=False)
        if proc.returncode != 0:
            raise IampError(f"netconvert failed ({proc.returncode}): {proc.stderr.strip()[:400]}")
        os.replace(work / "hw.net.xml", net)
    return net


def lane_centres(net: Path, edge: str = "hw") -> list[float]:
    """Lateral centre ``y`` of every lane of ``edge``, read from the built network."""
    import sumolib

    network = sumolib.net.readNet(str(net))
    return [float(lane.getShape()[0][1]) for lane in network.getEdge(edge).getLanes()]
