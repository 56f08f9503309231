import sys, json, time
from edeflare.data.generate import Recipe, generate_dataset
if __name__ == "__main__":
    cfg = json.loads(sys.argv[2])
    r = Recipe.from_dict(cfg)
    t = time.time()
    generate_dataset(r, sys.argv[1], workers=2)
    print("took", time.time() - t)
