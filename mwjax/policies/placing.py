"""Experts for the placing family (see mwjax/tasks/placing.py)."""

from __future__ import annotations
