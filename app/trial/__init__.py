"""The trial: its state (a fold over events), the event log, messages and the live runtime."""
