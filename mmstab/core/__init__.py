"""Inputs and shared services."""
