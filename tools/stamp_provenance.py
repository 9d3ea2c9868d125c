"""Give the suite pieces committed before provenance was recorded the provenance git can still tell.

``wfbench reproduce suite`` records in each piece's ``.json`` the commit, a hash of the code
and the hashes of the files the policy reads (:mod:`wfbench.reproduce.provenance`). Pieces
written before that have none. For each, this script takes the commit that last changed
the piece's ``.csv`` (the commit that published it) and computes, from git's objects of
that commit, the code hash and the sha256 of the policy's checkpoint or tuned files then.
It marks them ``"from": "git"``: the commit is the one that published the numbers, not
necessarily the tree they were computed on (a piece was usually computed on the working
tree that this commit recorded). ``wfbench reproduce verify`` is what says whether main
still computes them.

Usage::

    python tools/stamp_provenance.py docs/results/suite-v1-50
"""

from __future__ import annotations

import argparse
import hashlib
import json
import subprocess
import sys
from pathlib import Path

from wfbench.reproduce import provenance
from wfbench.reproduce.verify import pieces


def _git(repo: Path, *args: str) -> bytes:
    return subprocess.run(["git", "-C", str(repo), *args], capture_output=True, check=True).stdout


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("folder", type=Path, help="a suite run's folder (with cache/)")
    args = p.parse_args()
    repo = provenance.repository()
    if repo is None:
        print("stamp_provenance: run it from a git checkout of wfbench", file=sys.stderr)
        return 2
    code_at: dict[str, str] = {}
    stamped = 0
    for piece in pieces(args.folder):
        meta_path = piece.path.with_suffix(".json")
        meta = json.loads(meta_path.read_text())
        if meta.get("provenance"):
            continue
        rel = piece.path.resolve().relative_to(repo)
        commit = _git(repo, "log", "-1", "--format=%H", "--", str(rel)).decode().strip()
        if not commit:
            print(f"stamp_provenance: {rel} is not committed; recompute it instead", file=sys.stderr)
            return 1
        if commit not in code_at:
            code_at[commit] = provenance.code_sha256_at(repo, commit)
        inputs = {}
        for name in provenance.policy_inputs(piece.policy):  # the files the policy reads, as of that commit
            try:
                inputs[name] = hashlib.sha256(_git(repo, "show", f"{commit}:{name}")).hexdigest()
            except subprocess.CalledProcessError:
                continue  # the file did not exist then (a later candidate of the oracle)
        meta["provenance"] = {"commit": commit, "dirty": None, "code_sha256": code_at[commit], "inputs": inputs,
                              "from": "git"}
        meta_path.write_text(json.dumps(meta))
        stamped += 1
    print(f"stamped {stamped} pieces from git history ({len(code_at)} commits)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
