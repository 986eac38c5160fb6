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

    def lane_centre(self, lane: int) -> float:
        """``y_k = -(lanes - k - 1/2)·w`` (SUMO spreads lanes to the right of the edge line)."""
        return -(self.lanes - lane - 0.5) * self.lane_width

    def lane_of(self, y: float) -> int:
        """Index of the lane whose band contains ``y`` (clipped to the road)."""
        k = int(self.lanes - 1 - (-y) // self.lane_width)
        return min(max(k, 0), self.lanes - 1)

    def key(self) -> str:
        text = f"{self.length:.3f}|{self.lanes}|{self.lane_width:.3f}|{self.speed_limit:.3f}|{self.edge}"
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def nodes_xml(self) -> str:
        return ('<nodes>\n'
                '    <node id="start" x="0.0" y="0.0" type="priority"/>\n'
                f'    <node id="end" x="{self.length:.3f}" y="0.0" type="priority"/>\n'
                '</nodes>\n')

    def edges_xml(self) -> str:
        return ('<edges>\n'
                f'    <edge id="{self.edge}" from="start" to="end" numLanes="{self.lanes}" '
                f'speed="{self.speed_limit:.3f}" width="{self.lane_width:.3f}" priority="1"/>\n'
                '</edges>\n')


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
        cmd = [netconvert, "-n", "hw.nod.xml", "-e", "hw.edg.xml", "-o", "hw.net.xml",
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
