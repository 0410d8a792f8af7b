"""Experts for the ball family (see mwjax/tasks/ball.py)."""

from __future__ import annotations
