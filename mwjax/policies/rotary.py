"""Experts for the rotary family (see mwjax/tasks/rotary.py)."""

from __future__ import annotations
