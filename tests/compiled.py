"""The compiled parts (plan/native.py) must be there where their tests run: built by
`pip install` (setup.py). Outside CI a machine without a C compiler skips; in CI the
test fails, so the comparison with the Python always runs there."""

from __future__ import annotations

import os

import pytest


def require(built: bool, what: str) -> None:
    """Skip or fail (in CI) unless `what` was built."""
    if built:
        return
    message = f"the compiled {what} is not built (no C compiler, gcc, when the package " \
              f"was installed)"
    if os.environ.get("CI"):
        pytest.fail(message)
    pytest.skip(message)
