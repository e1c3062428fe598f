"""Text in the pictures: strips of captions and titles whose text is sized to fit, and shortened
with ".." rather than cut or overlapping (OpenCV's Hershey font; colours BGR)."""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

FONT = cv2.FONT_HERSHEY_SIMPLEX
TEXT_COLOR, STRIP_COLOR = (235, 235, 235), (25, 25, 25)
SMALLEST_SCALE = 0.3  # below this Hershey text is unreadable: shorten the text instead


def fit_text(text: str, width: int, height: int) -> tuple[str, float]:
    """text and a font scale such that it fits width x height pixels, shortened in the middle
    (".." standing for what was left out) where the smallest readable scale is too large."""
    scale = max((height - 6) / 30, SMALLEST_SCALE)  # Hershey simplex: 22 px of letters at scale 1, and a margin
    room = width - 6
    text_width = cv2.getTextSize(text, FONT, scale, 1)[0][0]
    if text_width > room:
        scale = max(scale * room / text_width, SMALLEST_SCALE)
    shown, keep = text, len(text)
    while keep > 0 and cv2.getTextSize(shown, FONT, scale, 1)[0][0] > room:
        keep -= 1
        shown = text[: (keep + 1) // 2] + ".." + text[len(text) - keep // 2 :]
    return shown, scale


def text_strip(texts: Sequence[tuple[str, int]], height: int) -> np.ndarray:
    """A strip (height, sum of widths, 3) with each text in its own column of the given width."""
    strip = np.full((height, sum(width for _, width in texts), 3), STRIP_COLOR, np.uint8)
    left = 0
    for text, width in texts:
        shown, scale = fit_text(text, width, height)
        (_, h), _ = cv2.getTextSize(shown, FONT, scale, 1)
        cv2.putText(strip, shown, (left + 3, (height + h) // 2), FONT, scale, TEXT_COLOR, 1, cv2.LINE_AA)
        left += width
    return strip
