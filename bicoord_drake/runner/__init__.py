"""Runners: demonstration generation and policy evaluation."""
