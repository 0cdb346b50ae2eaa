"""The wire protocol between host and firmware, defined once (docs/protocol.md).

Everything both sides must agree on lives in `spec`: the protocol version,
the line format and its check (CRC-16 behind a parity separator), the command
mnemonics with their argument kinds, the numbered error codes with their texts, the machine states and the real-time
bytes. The firmware's `firmware/galileo/protocol.h` is generated from it
(`python -m galileo_cnc.firmware_headers`) and a
test keeps the committed header equal to the generated text.

Host -> firmware, one command per line (at most MAX_LINE_BYTES with the newline):

    N<seq> <mnemonic>[ <int>]<* or #><CRC-16 as four upper-case hex digits>\\n

Firmware -> host, exactly one reply per line (`ok`, `error:`, `rs`), plus the
unsolicited banner, `status:`, `alarm:` and `msg:` lines, each with the same check.
"""

from galileo_cnc.protocol.codec import *  # noqa: F401,F403  framing and replies
from galileo_cnc.protocol.spec import *  # noqa: F401,F403  the definitions
