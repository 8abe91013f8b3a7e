"""`robotslang report agreement|study`: the annotators' agreement, and the paper's dataset
section computed from a study's trials (`study`: the numbers, `figures`: the PNGs, `markdown`:
the text) or from the public benchmark's files (`benchmark`)."""
