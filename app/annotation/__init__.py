"""Annotation of recorded trials (issue 25): the end of localization and the dialog phenomena,
written by annotators into a log of their own, compared between annotators and adjudicated.

`events` (the typed annotation events), `log` (the table that holds them and the current state
they add up to), `access` (the annotator's login), `assign` (who annotates what), `agreement`
(Cohen's kappa, cut distances, disagreements), `cli` (`robotslang annotate ...`).
"""
