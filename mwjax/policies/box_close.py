"""Experts for the box_close family (see mwjax/tasks/box_close.py)."""

from __future__ import annotations
