from os import PathLike

from _typeshed import WriteableBuffer

def read_columns(path: str | bytes | PathLike[str], out: WriteableBuffer, ncols: int, /) -> int: ...
