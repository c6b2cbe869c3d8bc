"""Whether a JPEG file is whole: a truncated one still decodes (OpenCV fills
the missing blocks with grey and only prints libjpeg's "Premature end of JPEG
file"), so a frame folder with a cut file would silently give grey frames.

A JPEG stream (ITU-T T.81, annex B) is a sequence of marker segments from SOI
(``FF D8``) to EOI (``FF D9``); each start of scan (``FF DA``) is followed by
entropy-coded data in which a ``FF`` byte is followed only by ``00`` (stuffing)
or a restart marker ``D0``–``D7``.  Walking the segments from the start, and
skipping each scan's data to its next real marker, finds EOI in a whole file;
a truncated one ends first.  Data after EOI (camera trailers, motion-photo
videos) is never read.
"""

from __future__ import annotations

__all__ = ["jpeg_truncated"]

_SOI, _EOI, _SOS, _TEM = 0xD8, 0xD9, 0xDA, 0x01


def jpeg_truncated(data: bytes) -> bool:
    """True when ``data`` is a JPEG stream that ends before its EOI marker.

    Data that does not start with SOI, or whose segments are not where a
    marker should be, is not judged here (False): the decoder says what it
    makes of it."""
    n = len(data)
    if data[:2] != bytes((0xFF, _SOI)):
        return False
    pos = 2
    while True:
        if pos + 1 >= n:
            return True
        if data[pos] != 0xFF:
            return False
        marker = data[pos + 1]
        if marker == 0xFF:  # fill byte before a marker
            pos += 1
            continue
        if marker == _EOI:
            return False
        if 0xD0 <= marker <= 0xD7 or marker == _TEM:  # markers without a length
            pos += 2
            continue
        if pos + 3 >= n:
            return True
        pos += 2 + ((data[pos + 2] << 8) | data[pos + 3])
        if marker != _SOS:
            continue
        while True:  # the scan's entropy-coded data, up to the next marker
            pos = data.find(b"\xff", pos)
            if pos < 0 or pos + 1 >= n:
                return True
            following = data[pos + 1]
            if following == 0x00 or 0xD0 <= following <= 0xD7:
                pos += 2
            elif following == 0xFF:
                pos += 1
            else:
                break
