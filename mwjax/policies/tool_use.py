"""Experts for the tool_use family (see mwjax/tasks/tool_use.py)."""

from __future__ import annotations
