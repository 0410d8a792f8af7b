"""Experts for the articulated family (see mwjax/tasks/articulated.py)."""

from __future__ import annotations
