"""ema-bench: model-based fault identification benchmark for aircraft EM actuators."""

__version__ = "0.1.0"
