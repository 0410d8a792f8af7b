"""Experts for the peg family (see mwjax/tasks/peg.py)."""

from __future__ import annotations
