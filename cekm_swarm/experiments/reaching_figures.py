"""Section 4.1's figures from a results document: Fig. 5 (learning curves), Fig. 6 (the
trained networks' input weights) and Fig. 7 (P, T, D against eps). matplotlib is
imported inside the function (Agg)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def plot_all(results: dict, trained: dict, out_dir: Path) -> list[Path]:
    """Fig. 5 (learning curves), Fig. 6 (input weights), Fig. 7 (P, T, D against eps)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    paths = []
    colours = {"B15": "tab:brown", "D15": "tab:orange", "G9": "tab:green", "G12": "tab:olive", "G15": "tab:cyan",
               "R15": "tab:blue"}
    nets = results["networks"]

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for name, e in nets.items():
        c = e["learning_curves"]
        steps = np.array(c["steps"]) / 1000.0
        for ax, key in zip(axes, ("E_mm", "T_s_per_m"), strict=True):
            per_trial = np.array(c[key]["per_trial"])
            ax.plot(steps, per_trial.mean(axis=0), "-o", ms=3, label=name, color=colours.get(name))
            ax.fill_between(steps, per_trial.min(axis=0), per_trial.max(axis=0), alpha=0.12, color=colours.get(name))
    axes[0].set_ylabel("mean positioning error E (mm)")
    axes[1].set_ylabel("normalized time-to-target T (s/m)")
    for ax, letter in zip(axes, "AB", strict=True):
        ax.set_yscale("log")
        ax.set_xlabel("training steps (thousands)")
        ax.set_title(f"({letter})", loc="left")
        ax.grid(alpha=0.3)
    axes[1].legend(ncol=2, fontsize=8)
    fig.suptitle("Fig. 5: learning curves (mean over trials; band: range over trials)")
    fig.tight_layout()
    paths.append(out_dir / "fig5_learning_curves.png")
    fig.savefig(paths[-1], dpi=120)
    plt.close(fig)

    paper = ("G9", "G12", "G15", "R15", "D15", "B15")
    order = [n for n in paper if n in trained] + [n for n in trained if n not in paper]
    cols = 3
    rows = int(np.ceil(len(order) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(4 * cols, 3.3 * rows), squeeze=False)
    for ax, name, letter in zip(axes.flat, order, "ABCDEFGHIJKL", strict=False):
        w = trained[name].w
        ax.scatter(w[:, 0], w[:, 1], s=6, color="k")
        ax.set_xlim(-np.pi, np.pi)
        ax.set_ylim(-0.005, max(0.17, float(w[:, 1].max()) + 0.005))
        ax.set_title(f"({letter}) {name}", loc="left")
        ax.set_xlabel("alpha (rad)")
        ax.set_ylabel("d (m)")
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[len(order):]:
        ax.axis("off")
    fig.suptitle("Fig. 6: self-organized input weights w_i = (alpha_i, d_i), trial 1")
    fig.tight_layout()
    paths.append(out_dir / "fig6_input_weights.png")
    fig.savefig(paths[-1], dpi=120)
    plt.close(fig)

    fig, axes = plt.subplots(1, 3, figsize=(14, 4))
    for name, e in nets.items():
        ec = e["eps_curves"]
        eps = np.array(ec["eps_mm"])
        for ax, key in zip(axes, ("P", "T_s_per_m", "D"), strict=True):
            mean = np.array([np.nan if v is None else v for v in ec[key]["mean"]], dtype=float)
            ax.plot(eps, mean, label=name, color=colours.get(name))
    for ax, label, letter in zip(axes, ("target reaching probability P(eps)", "normalized time-to-target T(eps) (s/m)",
                                        "mean deviation D(eps)"), "ABC", strict=True):
        ax.set_xlabel("eps (mm)")
        ax.set_ylabel(label)
        ax.set_title(f"({letter})", loc="left")
        ax.grid(alpha=0.3)
    axes[1].set_yscale("log")
    axes[0].legend(fontsize=8)
    fig.suptitle("Fig. 7: after training, against the reaching radius eps")
    fig.tight_layout()
    paths.append(out_dir / "fig7_eps_curves.png")
    fig.savefig(paths[-1], dpi=120)
    plt.close(fig)
    return paths
