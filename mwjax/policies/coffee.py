"""Experts for the coffee family (see mwjax/tasks/coffee.py)."""

from __future__ import annotations
