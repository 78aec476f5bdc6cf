"""The rendering layer: the terminal tables, the published tables printed beside them, the
HTML report and the figures (:mod:`reports.render.figures`), drawn from what
:mod:`reports.scoring` computes."""
