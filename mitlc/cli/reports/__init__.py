"""``mitlc report``: a training's, a sweep's or a verification's folder as one self-contained HTML page.

In: a folder ``mitlc train``, ``mitlc sweep`` or ``mitlc verify --out`` wrote. Out: the text of ``report.html``: its
scripts, styles and pictures inline, so the one file opens by double-click, with no network.

* :mod:`~mitlc.cli.reports.training`: what a training's page shows, gathered from the folder
  (its learner loaded again, each run's greedy rollout stepped through the runtime, judged by the
  monitor);
* :mod:`~mitlc.cli.reports.sweep`: what a sweep's page shows, from its ``results.json``;
* :mod:`~mitlc.cli.reports.verification`: what a verification's page shows, from its ``report.json``
  and the counterexamples' figures beside it;
* :mod:`~mitlc.cli.reports.page`: the HTML around them (``report.css``, ``report.js``).

A part of the command line (it loads learners, steps the runtime and asks the monitor), so it
may import every stage; :mod:`mitlc.cli.report` is the command.
"""

from mitlc.cli.reports.page import REPORT, report_html

__all__ = ["REPORT", "report_html"]
