"""How a path through the graph is joined into motion (``synthesize``): one settings
object that the avatar, the sketch interface and the vision loop hand down."""

from __future__ import annotations

from dataclasses import dataclass

from ._ik import TURN_RATE

__all__ = ["BlendSettings"]


@dataclass(frozen=True)
class BlendSettings:
    """How ``synthesize`` blends transitions and keeps planted feet.

    Attributes
    ----------
    seconds : float
        The blend interval b over which a transition's displacement decays (Lee et al.:
        1-2 s).
    ik : bool
        Keep planted feet in place with leg IK.
    fade : float
        Seconds over which a foot's correction fades after it lifts.
    max_offset : float
        Metres: a planted foot held further than this from where the blended motion puts
        it slides along instead (the paper's "allow the foot to slip").
    anchor : str
        Where a planted foot is held: ``"output"`` where it touched down in the blended
        motion; ``"source"`` where its source frame puts it under the path's alignment
        (on terrain, the block top the path was checked against).
    feet : str
        ``"held"``: a planted foot held where it touched down; ``"floor"``: brought to
        the source frame's height over each blend (the vision avatar, whose blends never
        end; on terrain, or walks of the graph, ``"held"`` slides less).
    turn_limit : float or None
        Degrees a second: no blended joint turns in a frame more than this beyond what its
        source frame turns (``follow_turns``; ``None``: no limit).
    ik_turn_rate : float
        Degrees a second: the most the leg IK's corrections turn a joint in a frame.
    """

    seconds: float = 1.0
    ik: bool = True
    fade: float = 0.25
    max_offset: float = 0.2
    anchor: str = "output"
    feet: str = "held"
    turn_limit: float | None = None
    ik_turn_rate: float = TURN_RATE

    def frames(self, fps: float) -> int:
        """The blend interval in frames at ``fps`` (at least one)."""
        return max(1, round(self.seconds * fps))

    def __post_init__(self) -> None:
        if not self.seconds > 0 or not self.fade >= 0 or not self.max_offset >= 0:
            raise ValueError(
                "the blend's seconds must be positive, fade and max_offset not negative, "
                f"got {self.seconds}, {self.fade} and {self.max_offset}"
            )
        if self.anchor not in ("output", "source"):
            raise ValueError(f"anchor must be 'output' or 'source', not {self.anchor!r}")
        if self.feet not in ("held", "floor"):
            raise ValueError(f"feet must be 'held' or 'floor', not {self.feet!r}")
        if not (self.turn_limit is None or self.turn_limit > 0) or not self.ik_turn_rate > 0:
            raise ValueError("turn_limit and ik_turn_rate must be degrees a second > 0")
