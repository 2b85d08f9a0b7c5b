"""mrnc-eval: offline log processing and evaluation for skid-steer field robots."""

__version__ = "0.1.0"
