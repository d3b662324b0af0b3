"""Drawing and encoding a MuJoCo video, two ways, alternating in one process: every frame drawn
first and then encoded (how rlq wrote videos before), and each frame handed to ffmpeg as it is drawn
(``rlq.store.render.write_video`` on the env's ``draw_frames``, how the final video is written now).

The poses are a made-up walk of brax's humanoid (``qpos0`` moved along x, the joints swinging), as
many as a 1000-step episode gives (1001 frames at 640 x 480). ``MUJOCO_GL`` picks the backend (egl on
a GPU node); the process's cores are shared by the drawing (this process) and ffmpeg.

    MUJOCO_GL=egl python scripts/bench_video.py --frames 1001 --repeat 3 --out video.json
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from rlq.envs.humanoid.env import Humanoid
from rlq.store.render import write_video


def walk(env: Humanoid, frames: int) -> dict[str, np.ndarray]:
    qpos = np.tile(env.mj_model.qpos0, (frames, 1))
    qpos[:, 0] = np.linspace(0.0, 10.0, frames)
    qpos[:, 7:] = 0.3 * np.sin(np.linspace(0.0, 60.0, frames))[:, None]
    return {"qpos": qpos}


def drawn_then_encoded(env: Humanoid, arrays: dict[str, np.ndarray], path: Path) -> dict:
    start = time.perf_counter()
    frames = env.draw(arrays)
    drawn = time.perf_counter()
    write_video(path, frames, env.render_fps)
    end = time.perf_counter()
    return {"draw_s": round(drawn - start, 2), "encode_s": round(end - drawn, 2), "total_s": round(end - start, 2)}


def streamed(env: Humanoid, arrays: dict[str, np.ndarray], path: Path) -> dict:
    start = time.perf_counter()
    write_video(path, env.draw_frames(arrays), env.render_fps)
    return {"total_s": round(time.perf_counter() - start, 2)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=1001)
    parser.add_argument("--repeat", type=int, default=3, help="rounds, each running both ways")
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()

    env = Humanoid()
    arrays = walk(env, args.frames)
    rounds = []
    with tempfile.TemporaryDirectory() as tmp:
        for index in range(args.repeat):
            ways = [("drawn_then_encoded", drawn_then_encoded), ("streamed", streamed)]
            if index % 2:
                ways.reverse()
            row = {}
            for name, way in ways:
                path = Path(tmp) / f"{name}.mp4"
                row[name] = {**way(env, arrays, path), "mp4_bytes": path.stat().st_size}
            rounds.append(row)
            print(json.dumps(row))
    report = {
        "benchmark": "video",
        "date": time.strftime("%Y-%m-%d"),
        "mujoco_gl": os.environ.get("MUJOCO_GL"),
        "cores": os.cpu_count(),
        "frames": args.frames,
        "rounds": rounds,
        "median_total_s": {
            name: float(np.median([row[name]["total_s"] for row in rounds]))
            for name in ("drawn_then_encoded", "streamed")
        },
    }
    print(json.dumps(report["median_total_s"]))
    if args.out:
        args.out.write_text(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
