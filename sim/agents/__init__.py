"""Agents that take a seat in a trial: typed percepts in, typed turns out (pure domain: no web, no database)."""
