"""Glue that runs a log end to end, a folder, a night. IO lives here, algorithms do not."""
