"""Experts for the handles family (see mwjax/tasks/handles.py)."""

from __future__ import annotations
