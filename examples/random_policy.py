"""A random policy on renderloop/PepperScan-v0: a few episodes, each one plant scanned from random viewpoints.

    .venv/bin/python examples/random_policy.py [--episodes 3] [--seed 0] [--max-views 8]

Prints, per episode, the plant, the return, the views flown, the fruit confirmed (ripe among them)
and the plant's truth from the scene. About 10 to 15 s an episode on 2 cores.
"""

from __future__ import annotations

import argparse

import gymnasium

import renderloop  # noqa: F401  (registers renderloop/PepperScan-v0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0, help="seeds the first reset and the policy")
    parser.add_argument("--max-views", type=int, default=8, help="views flown per episode")
    args = parser.parse_args()

    env = gymnasium.make("renderloop/PepperScan-v0", max_views=args.max_views)
    env.action_space.seed(args.seed)
    print(f"{'episode':>7} {'plant':>5} {'return':>8} {'views':>5} {'flight s':>8} {'confirmed':>9} {'ripe':>4} "
          f"{'truth':>5} {'ripe':>4}")
    try:
        for episode in range(args.episodes):
            observation, info = env.reset(seed=args.seed if episode == 0 else None)
            total, views, done = 0.0, 0, False
            while not done:
                observation, reward, terminated, truncated, info = env.step(env.action_space.sample())
                total, views, done = total + reward, views + 1, terminated or truncated
            print(f"{episode:>7} {info['plant']:>5} {total:>8.2f} {views:>5} {observation['counter'][3]:>8.1f} "
                  f"{info['confirmed']:>9} {info['confirmed_ripe']:>4} {info['true_fruit']:>5} {info['true_ripe']:>4}")
    finally:
        env.close()


if __name__ == "__main__":
    main()
