"""Child process for the SIGKILL test: append frames forever, report each append.

Usage: ``python recording_writer_child.py OUT.h5 RATE_HZ``. Frame ``i`` is filled with
``i % 65536`` and has frame id ``i``. After every append it prints ``appended N`` and
flushes stdout, so the parent knows what the writer had been given before it was killed.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from holoview.acquire.recording_writer import RecordingWriter


def main() -> None:
    path, rate = sys.argv[1], float(sys.argv[2])
    with RecordingWriter(path, (48, 64), np.uint16, source="sigkill-test") as writer:
        i = 0
        while True:
            frame = np.full((48, 64), i % 65536, np.uint16)
            writer.append(frame, i, i / rate, time.time())
            i += 1
            print(f"appended {i}", flush=True)
            time.sleep(1.0 / rate)


if __name__ == "__main__":
    main()
