"""Experts for the plate_slide family (see mwjax/tasks/plate_slide.py)."""

from __future__ import annotations
