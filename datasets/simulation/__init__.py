"""Seeded simulator with exact ground truth (scenarios in ``scenarios``, folder format in
``folder_format``). Submodules are imported on use, so that importing the package is cheap."""
