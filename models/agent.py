"""The NDH seq2seq Driver: a dialog encoder and an action decoder over ray observations.

Encoder: word embeddings (128) -> LSTM (128) over the dialog tokens. Its final state starts the
decoder LSTM (128), which at each step reads the encoded ray observation and the embedding (8)
of the previous action, and scores forward/left/right/stop. Forward is masked wherever it
would collide. Four options go beyond the paper's model: attention over the dialog at each
step, a progress monitor (an auxiliary head predicting how much of the way is done), target
flags (which rays see the object being looked for), and a critic (a value head for training
on the distance covered, `models.rollout`).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn

from models.tokenizer import MAX_TOKENS
from sim.core.dynamics import Action
from sim.core.labels import N_LABELS
from sim.core.observations import N_RAYS

# The simulator's action ids, as plain ints for tensor indexing.
FORWARD, LEFT, RIGHT, STOP = (int(a) for a in (Action.FORWARD, Action.LEFT, Action.RIGHT, Action.STOP))
N_ACTIONS = len(Action)
START = N_ACTIONS  # the "previous action" at the first step
NEG_INF = -1e9
STOP_THRESHOLD = 0.9  # the stop head's probability above which the greedy agent stops; chosen on val_seen


@dataclass
class AgentConfig:
    vocab_size: int
    obs_features: int
    embed: int = 128
    hidden: int = 128
    obs_hidden: int = 128
    action_embed: int = 8
    dropout: float = 0.5
    attention: bool = False
    progress_monitor: bool = False
    target_rays: bool = False  # add, per ray, whether it sees the target object
    critic: bool = False  # a value head, for the actor-critic loss on the distance covered
    stop_head: bool = False  # P(within the success radius), which decides the greedy agent's stop
    # At test time, each earlier visit of the pose a move leads to lowers that move's logit by
    # this much (0: off): a greedy Driver otherwise turns on the spot or shuttles to the cap.
    revisit_penalty: float = 0.0
    attention_dim: int = 32  # keys and values are projected once per dialog, so each step is cheap
    context_tokens: int = MAX_TOKENS  # the encoder's fixed (left-padded) input width

    @property
    def obs_inputs(self) -> int:
        return self.obs_features + (N_RAYS if self.target_rays else 0)


class Seq2SeqAgent(nn.Module):
    def __init__(self, config: AgentConfig):
        super().__init__()
        self.config = config
        c = config
        self.embedding = nn.Embedding(c.vocab_size, c.embed, padding_idx=0)
        self.encoder = nn.LSTM(c.embed, c.hidden, batch_first=True)
        self.drop = nn.Dropout(c.dropout)
        self.obs_encoder = nn.Sequential(nn.Linear(c.obs_inputs, c.obs_hidden), nn.ReLU())
        self.action_embedding = nn.Embedding(N_ACTIONS + 1, c.action_embed)
        self.decoder = nn.LSTMCell(c.obs_hidden + c.action_embed, c.hidden)
        if c.attention:
            self.attn_key = nn.Linear(c.hidden, c.attention_dim, bias=False)
            self.attn_value = nn.Linear(c.hidden, c.attention_dim, bias=False)
            self.attn_query = nn.Linear(c.hidden, c.attention_dim, bias=False)
            self.attn_out = nn.Linear(c.hidden + c.attention_dim, c.hidden)
        self.policy = nn.Linear(c.hidden, N_ACTIONS)
        if c.progress_monitor:
            self.progress = nn.Linear(c.hidden, 1)
        if c.critic:
            self.value = nn.Linear(c.hidden, 1)
        if c.stop_head:
            self.stop = nn.Linear(c.hidden, 1)

    def encode(self, tokens: torch.Tensor, lengths: torch.Tensor):
        """(B, T) ids, right-padded, and (B,) lengths -> context, its mask (B, W), initial state.

        The encoder reads each dialog left-padded to the fixed width W (`context_tokens`), so its
        last token is the last step for every dialog: one fused LSTM call, about 3x cheaper in
        training than packed sequences, and a lone dialog (the web Driver's) is read exactly as
        in training. The context is (B, W, H), or with attention its (keys, values) projections.

        A dialog of length 0 (the language-blind ablation) gets a zero state and no context.
        """
        width = self.config.context_tokens
        lengths = lengths.clamp(max=width)
        source = torch.arange(width).unsqueeze(0) - (width - lengths).unsqueeze(1)  # column in `tokens`
        ctx_mask = source >= 0
        left = tokens.gather(1, source.clamp(min=0, max=tokens.shape[1] - 1)).masked_fill(~ctx_mask, 0)
        out, (h, c) = self.encoder(self.drop(self.embedding(left)))
        keep = (lengths > 0).float().unsqueeze(1)
        h, c = h[0] * keep, c[0] * keep
        ctx = out * ctx_mask.unsqueeze(2).float()
        if self.config.attention:  # (keys, values) in place of the raw context
            ctx = (self.attn_key(ctx), self.attn_value(ctx))
        return ctx, ctx_mask, (h, c)

    def step(
        self,
        obs: torch.Tensor,
        prev_action: torch.Tensor,
        state,
        ctx,
        ctx_mask,
        forward_blocked: torch.Tensor,
        stop_allowed: torch.Tensor | None = None,
    ):
        """One decision: logits (B, 4) with the impossible actions masked, the new state, and the
        progress (B,), value (B,) and stop-probability (B,) heads' outputs (None where the agent
        has no such head)."""
        x = torch.cat([self.obs_encoder(obs), self.action_embedding(prev_action)], dim=1)
        h, c = self.decoder(self.drop(x), state)
        out = h
        if self.config.attention:
            keys, values = ctx
            scores = torch.bmm(keys, self.attn_query(h).unsqueeze(2)).squeeze(2)
            scores = scores.masked_fill(~ctx_mask, NEG_INF)
            weights = torch.softmax(scores, dim=1) * ctx_mask.any(dim=1, keepdim=True).float()
            attended = torch.bmm(weights.unsqueeze(1), values).squeeze(1)
            out = torch.tanh(self.attn_out(torch.cat([h, attended], dim=1)))
        logits = self.policy(self.drop(out))
        logits = mask_logits(logits, forward_blocked, stop_allowed)
        progress = torch.sigmoid(self.progress(out)).squeeze(1) if self.config.progress_monitor else None
        value = self.value(out).squeeze(1) if self.config.critic else None
        stop = torch.sigmoid(self.stop(out)).squeeze(1) if self.config.stop_head else None
        return logits, (h, c), progress, value, stop


def greedy_actions(
    logits: torch.Tensor,
    stop: torch.Tensor | None,
    stop_allowed: torch.Tensor | None = None,
    visits: torch.Tensor | None = None,
    revisit_penalty: float = 0.0,
) -> torch.Tensor:
    """The test-time decision: the best-scored action, or stop where the stop head (if any)
    is confident the goal is within reach and a stop is allowed. `visits` (B, 3): how often the
    episode has been in the pose that forward, left and right lead to; each visit costs that
    move `revisit_penalty` of its score."""
    if visits is not None and revisit_penalty:
        logits = logits.clone()
        logits[:, :STOP] -= revisit_penalty * visits
    action = logits.argmax(dim=1)
    if stop is None:
        return action
    claim = stop > STOP_THRESHOLD
    if stop_allowed is not None:
        claim &= stop_allowed
    return torch.where(claim, torch.full_like(action, STOP), action)


def observation_input(config: AgentConfig, obs: torch.Tensor, target_label: torch.Tensor) -> torch.Tensor:
    """The decoder's observation: ray features (B, F), plus the target flags when configured.

    The flags are the target's column of each ray's one-hot label: what a Driver looking for
    the mug notices first is the mug. A negative label (the target unknown: the language-blind
    ablation, where the target word goes with the dialog) gives no flags.
    """
    if not config.target_rays:
        return obs
    cols = torch.arange(N_RAYS).unsqueeze(0) * N_LABELS + target_label.clamp(min=0).unsqueeze(1)
    known = (target_label >= 0).float().unsqueeze(1)
    return torch.cat([obs, obs.gather(1, cols) * known], dim=1)


def mask_logits(
    logits: torch.Tensor, forward_blocked: torch.Tensor, stop_allowed: torch.Tensor | None = None
) -> torch.Tensor:
    """Forward is impossible where it would collide; stop, where given, only where allowed."""
    mask = torch.zeros_like(logits, dtype=torch.bool)
    mask[:, FORWARD] = forward_blocked
    if stop_allowed is not None:
        mask[:, STOP] = ~stop_allowed
    return logits.masked_fill(mask, NEG_INF)
