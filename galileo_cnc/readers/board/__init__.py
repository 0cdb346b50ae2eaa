"""A board: the files one EDA export holds and each file's role (docs/boards.md).

roles.py decides one file's role (X2, job file, header, name: names.py, headers.py),
board.py opens a folder, .zip or .gbrjob as a Board, describe.py says what `info BOARD`
prints.
"""

from galileo_cnc.readers.board.board import Board, BoardError, Layer, is_board, open_board
from galileo_cnc.readers.board.describe import describe_board
from galileo_cnc.readers.board.roles import ROLES

__all__ = ["Board", "BoardError", "Layer", "ROLES", "describe_board", "is_board", "open_board"]
