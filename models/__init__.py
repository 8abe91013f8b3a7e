"""Learning: NDH datasets, the seq2seq Driver agent, training, evaluation and statistics."""
