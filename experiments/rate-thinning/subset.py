"""A third of each part of a mix: every third sequence (by name, from the first) of each
part's train/ and test/ splits, hard-linked into OUT/<part>/<split>/.

Run: python subset.py MIX OUT
"""

import os
import sys
from pathlib import Path

from edeflare.data.folders import dataset_folders

src, dst = Path(sys.argv[1]), Path(sys.argv[2])
for part in dataset_folders(src):
    for split in ("train", "test"):
        files = sorted((part / split).glob("*.h5"))
        for f in files[::3]:
            out = dst / part.name / split / f.name
            out.parent.mkdir(parents=True, exist_ok=True)
            if not out.exists():
                os.link(f, out)
        print(part.name, split, len(files[::3]), "of", len(files))
