"""Report writing: figures (the only matplotlib importer), Markdown and self-contained HTML."""
