"""What a shipped student's deployable inputs cost it: its held-out success on its result's
episodes with the clouds and the object pose as deployed (the cameras' view with noise and
dropout; the estimate's error) and with either or both exact (every surface without noise;
the true pose). Equal rates mean the sensors' error is not what keeps the student from its
teacher: the rest is its own fit, chiefly of what it cannot observe at all (the teacher's
privileged physics and object velocity).

    python scripts/student_inputs.py easy-paddle-student
    python scripts/student_inputs.py runs/dagger-push

The last line printed is one JSON object: the success rate of each input setting.
"""

from __future__ import annotations

import argparse
import json

from hamnet.perception.config import student_clouds
from hamnet.policy.observation import PoseNoiseConfig
from hamnet.trainer.results.evaluate import evaluate
from hamnet.trainer.results.summary import policy_and_result, run_of

EXACT_POSE = PoseNoiseConfig(position_std=0.0, rotation_std=0.0)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "student",
        help="a shipped student's name (its card names its result) or a DAgger run's folder",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the result's evaluation")
    args = parser.parse_args()
    policy, result = policy_and_result(args.student)  # result: the run's summary fields
    if policy.config.privileged:
        parser.error(f"{args.student} reads privileged inputs: it is not a student")
    config, episodes = run_of(result, args.seed), result["eval_episodes"]
    settings = {
        "deployed": (student_clouds(), None),
        "exact_clouds": (None, None),
        "exact_pose": (student_clouds(), EXACT_POSE),
        "exact_both": (None, EXACT_POSE),
    }
    rates = {}
    for name, (clouds, pose_noise) in settings.items():
        held_out = evaluate(policy, config, episodes, result["env_steps"], clouds, pose_noise)
        rates[name] = held_out.success_rate
        print(f"{name}: {held_out.success_rate:.3f} on {episodes} held-out episodes", flush=True)
    print(json.dumps({"student": args.student, "episodes": episodes, **rates}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
