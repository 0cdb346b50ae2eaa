"""Stock GRBL 1.1h in the simavr harness: the board-building code lives beside the
harness in galileo_cnc.simavr.grbl_firmware (so `simavr://?firmware=grbl` can use
it without importing the GRBL backend); re-exported here for the GRBL side.
"""

from __future__ import annotations

from galileo_cnc.simavr.grbl_firmware import (  # noqa: F401  (re-exported)
    AXIS_PINS, BUILD_DIR, BUILD_PACKAGES, DEFAULT_SOURCE, ELF_NAME, GRBL_SOURCE_ENV,
    HARNESS_ARGS, LIMIT_PINS, OCR1A_AT_START, SPINDLE_PWM_PIN, TRACE_PINS, GrblBuildError,
    build_dir, build_grbl, grbl_board, source_digest, source_dir,
)
