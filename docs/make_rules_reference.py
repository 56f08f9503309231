"""Write docs/rules.md from the rules' registry: python docs/make_rules_reference.py"""

from pathlib import Path

from edeflare.rules import reference_markdown

if __name__ == "__main__":
    path = Path(__file__).with_name("rules.md")
    path.write_text(reference_markdown() + "\n", encoding="utf-8")
    print(f"wrote {path}")
