"""Evaluation: the paper's metrics, scoring streams and files, tables, benchmark and report.

- :mod:`~edeflare.eval.metrics`: per-window metrics (Chamfer, Gaussian, MSE, PSNR, ...).
- :mod:`~edeflare.eval.evaluate`: score streams, files or folders; aggregate over segments
  and sequences.
- :mod:`~edeflare.eval.authors`: the same eight metrics as the authors' evaluation code
  computes them (``convention="authors"``).
- :mod:`~edeflare.eval.tables`: :class:`~edeflare.eval.tables.ResultsTable`, the paper's
  table (best / second, improvement) and its one writer (``save``).
- :mod:`~edeflare.eval.benchmark`: every method on every sequence of a split, with speed.
- :mod:`~edeflare.eval.flare_score`, :mod:`~edeflare.eval.reconstruct`,
  :mod:`~edeflare.eval.report`: flare scores, intensity reconstruction and the HTML report.
- :mod:`~edeflare.eval.score`: scores on real recordings without ground truth.
- the composition ablation (train per variant, test) is :mod:`edeflare.ablate`, above both
  training and evaluation.

Nothing is imported here: ``import edeflare.eval.metrics`` loads what it needs.
"""
