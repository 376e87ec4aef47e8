"""What the commands write: each command's run, figures and ``summary.json`` in ``results/``.

One module per command's output: ``planning`` (``plan`` on a circle, Fig. 7 and Fig. 8;
``plan_quality`` its optimality check), ``routes`` (``plan`` on a route; ``verify``: ``plan
--verify``), ``tracking`` (``track``), ``animation``, ``stability_map``,
``simulate`` (+ ``simulate_figure``), ``recording`` (``record``), ``online`` (``follow``);
``common``: the output folder and the saved settings. The paper's other figures and the
studies are the repository's ``experiments/`` (``python -m experiments``), outside the
package.
"""
