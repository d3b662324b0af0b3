"""The matrix's figures measured before scripts/run_matrix.py (one to three seeds per pair, not per-seed data over
N seeds): docs/matrix.md shows them, marked older, for a pair until it has an N-seed result. Each: the figure in
a few words and the file or page it comes from."""

from __future__ import annotations

PLAIN_28 = "docs/results/matrix_plain_commands_h200_2026_11_28.json"
PLAIN_29 = "docs/results/matrix_plain_commands_h200_2026_11_29.json"

#: (env, algo) -> (figure, source); GPU = one H200, CPU = 2 CPU cores, seed 777 unless said
OLDER = {
    ("cartpole", "ppo"): ("1 seed: 500 in 16.4 s (GPU), 500 in 14.9 s (CPU)", PLAIN_28),
    ("cartpole", "dqn"): ("1 seed: 500 in 14.8 s (GPU), 500 in 21.3 s (CPU)", PLAIN_28),
    ("cartpole", "pqn"): ("1 seed: 500 in 11.3 s (GPU, 2 epochs), 500 in 12.9 s (CPU)", PLAIN_28),
    ("cartpole", "reinforce"): ("1 seed: 500 in 11.7 s (GPU), 500 in 11.3 s (CPU)", PLAIN_28),
    ("cartpole", "random_search"): ("1 seed: 500 in 5.0 s (GPU), 500 in 5.4 s (CPU)", PLAIN_28),
    ("cartpole", "map_elites"): ("1 seed: 500 in 8.3 s (GPU), 500 in 9.0 s (CPU)", PLAIN_28),
    ("cartpole", "es"): ("1 seed: 500 in 7.6 s (GPU), 500 in 22.5 s (CPU)", PLAIN_29),
    ("cartpole", "qlearning"): ("1 seed: 500 in 9.5 s (GPU), 500 in 13.8 s (CPU)", PLAIN_28),
    ("lunar", "ppo"): ("1 seed: Box2D 270.5 in 21.6 s (GPU), 263.2 in 141.9 s (CPU)", PLAIN_28),
    ("lunar", "dqn"): ("3 seeds: Box2D 261.4, 200.4, 224.3 in 47-52 s (GPU)", PLAIN_29),
    ("lunar", "pqn"): ("1 seed: Box2D 271.3 in 36.6 s (GPU)", PLAIN_28),
    ("lunar", "es"): (
        "3 seeds, 256 candidates (the recipe before): Box2D 259.0, 253.5, 255.0 in 57-65 s (GPU)",
        PLAIN_29,
    ),
    ("humanoid", "ppo"): (">= 6000 in 87 of 91 runs, 42-50 s cold (GPU)", "docs/humanoid.md"),
    ("humanoid", "reinforce"): (
        "tuning seed 100: greedy 485 of 6000 in 438 s beside 3 other runs (GPU)",
        "docs/results/matrix_h200_2026_12_02.json",
    ),
    ("brittle_star", "ppo"): ("2.81 m of 3 (CPG, 193 s), 2.31 m (direct)", "docs/brittle_star.md"),
    ("brittle_star", "qlearning"): ("decentralised, 3 seeds: 0.54, 0.53, 0.53 m in 214-366 s", "docs/brittle_star.md"),
    ("brittle_star_undirected", "map_elites"): ("QD score 200-256 in 41 s", "docs/map_elites.md"),
    ("brittle_star_undirected", "random_search"): ("QD score 81-86 in 42-44 s", "docs/map_elites.md"),
    ("brittle_star_undirected", "es"): ("3 seeds: 1.443, 1.475, 1.492 m (GPU)", "docs/results/h200_2026_12_01.json"),
}
