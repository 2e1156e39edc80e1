"""The package's version: a leaf module, so that modules inside the package read it without
importing the package face (``ema_bench/__init__.py``), which imports most of them."""

__version__ = "0.2.0"
