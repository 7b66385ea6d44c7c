"""A text progress bar for the long studies (on stderr, so that stdout keeps the tables)."""

from __future__ import annotations

import sys
from typing import TextIO


def report_progress(done: int, total: int, what: str, width: int = 24,
                    stream: TextIO | None = None) -> None:
    """Print one line ``[#####.......]  5/16  <what>``: ``done`` of ``total`` steps finished,
    the last being ``what``."""
    filled = round(width * done / total) if total else width
    print(f"[{'#' * filled}{'.' * (width - filled)}] {done:>{len(str(total))}}/{total}  {what}",
          file=sys.stderr if stream is None else stream, flush=True)
