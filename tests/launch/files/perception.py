"""Stands for a perception program in the launch files of the tests (never run)."""
