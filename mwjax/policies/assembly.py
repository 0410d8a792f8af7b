"""Experts for the assembly family (see mwjax/tasks/assembly.py)."""

from __future__ import annotations
