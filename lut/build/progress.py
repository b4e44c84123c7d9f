"""A build's progress bar on stderr: points done, failed, the last status and the time left."""

from __future__ import annotations

import sys

from lut.table.point_result import PointResult, PointStatus


class Progress:
    """tqdm's bar over the grid's points (nothing at all when disabled: logs, CI)."""

    def __init__(self, total: int, initial: int, enabled: bool, desc: str = "build") -> None:
        self.failed = 0
        self.bar = None
        if enabled:
            from tqdm import tqdm

            self.bar = tqdm(total=total, initial=initial, unit="point", desc=desc, dynamic_ncols=True,
                            file=sys.stderr)

    def update(self, result: PointResult) -> None:
        if result.status is PointStatus.FAILED:
            self.failed += 1
        if self.bar is not None:
            self.bar.set_postfix(failed=self.failed, last=result.status.value)
            self.bar.update(1)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
