"""Where a stream's frames stop following each other: a replay's jumps.

A replay source stamps every frame with its ``segment``
(:class:`~holoview.acquire.source.FrameMeta`): a seek (even to the frame after the
one shown), a step back or the loop starting over opens a new one; frames a consumer
skipped do not. The maps and the series take different frames (the
newest, every one), so neither can tell a jump from frames it skipped by the
indices alone; both ask a :class:`Continuity` instead. At a break the maps forget
the previous frame (:meth:`~holoview.engine.frame_core.FrameCore.break_sequence`: no
relative map pairs frames from before and after a jump) and the series starts over
(no rate is fitted across a jump). A camera's frames are all in segment 0.
"""

from __future__ import annotations

from holoview.acquire.source import FrameMeta

__all__ = ["Continuity"]


class Continuity:
    """Follow the segments of the frames one consumer takes.

    Examples
    --------
    >>> from holoview.acquire.source import FrameMeta
    >>> c = Continuity()
    >>> [c.breaks(FrameMeta(i, 0.0, 0.0, file_index=i, segment=s)) for i, s in enumerate([0, 0, 1])]
    [False, False, True]
    """

    def __init__(self) -> None:
        self.segment: int | None = None

    def breaks(self, meta: FrameMeta) -> bool:
        """Take the next frame's ``meta``; True when it opens another segment than the last.

        The first frame breaks nothing.
        """
        broken = self.segment is not None and meta.segment != self.segment
        self.segment = meta.segment
        return broken
