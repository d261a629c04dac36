"""The writers of this repository's own documents: the generated blocks of ``README.md`` and
``docs/*.md`` and the frontier's figure, rendered from committed records by
``scripts/render_docs.py`` (and the results tag ``scripts/results_index.py`` reads). They live
here, out of the installed package: ``snnkart`` keeps what a user runs (its reports, study
summaries and the frontier's numbers, :func:`snnkart.report.frontier.frontier`), and imports
nothing from here.

A script beside this folder imports it as ``docs_blocks`` (``python scripts/render_docs.py``
puts ``scripts/`` on ``sys.path``); a test puts ``scripts/`` on ``sys.path`` first.
"""
