"""Parameter counts of every registered architecture next to the paper's (`hamnet policy
--print-params`).

The paper reports counts only for the MLP scaling study (Table tab:mlp-scale): the MLP
(768, 384, 384, 192) has 1.76 M parameters, sized "to approximately match" HAMnet with
M = 8, and the base-size MLP (256, 128, 128, 64) 0.36 M. Both of the paper's numbers fit an
actor and a critic MLP on a ~465-wide input and nothing else, so the table shows our base
networks (actor + critic, whatever builds their weights) beside the total. Our MLP's widths
are the paper's scaled so that its total matches our HAMnet's (`ModelConfig.mlp_hidden`).
"""

from __future__ import annotations

from hamnet.policy.registry import ARCHITECTURES, build


def counts(name: str) -> tuple[int, int]:
    """(total, actor + critic) trainable parameters of architecture `name`."""
    network = build(name).network
    total = sum(p.numel() for p in network.parameters())
    base = sum(p.numel() for part in (network.actor, network.critic) for p in part.parameters())
    return total, base


def parameter_table() -> str:
    """The table `--print-params` prints."""
    lines = [f"{'architecture':<15} {'total':>10} {'actor+critic':>13}  paper", "-" * 96]
    for name, entry in ARCHITECTURES.items():
        total, base = counts(name)
        lines.append(f"{name:<15} {total / 1e6:>9.3f}M {base / 1e6:>12.3f}M  {entry.paper_params}")
    lines += [
        "",
        "total: everything trained, from tokens to actions (cross-attentions, modulation or",
        "hyper/routing networks, base networks). actor+critic: the base networks' own weights",
        "(HAMnet: its module banks; hyper: the heads that generate them). The paper gives",
        "counts only in Table tab:mlp-scale (MLP 768-384-384-192: 1.76 M, matched to HAMnet);",
        "our MLP is those widths x 1.103, matched to our HAMnet's total the same way. With",
        "the authors' 196-wide base input, HAMnet's base networks hold 1.742 M (paper: 1.76 M).",
    ]
    return "\n".join(lines)
