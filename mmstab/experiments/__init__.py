"""Experiments of the paper, one function per ``make`` target, each writing ``results/<name>/``."""
