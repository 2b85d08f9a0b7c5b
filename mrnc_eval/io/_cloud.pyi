from _typeshed import ReadableBuffer, WriteableBuffer

def gather(data: ReadableBuffer, shape: tuple[int, int, int, int], xyz: tuple[int, int, int],
           points: WriteableBuffer, columns: tuple[tuple[int, int, int, WriteableBuffer], ...], /) -> int: ...
