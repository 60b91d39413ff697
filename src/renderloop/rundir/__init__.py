"""The run directory: the one contract between the pipeline's stages.

- `names`: every file of a run, named once, and which stage writes which.
- `models`: the JSON files as pydantic models.
- `files`: a typed reader and writer per file; the only way stages read each other's files.
- `stage`: the Stage every pipeline step is, with its require / complete / skip check.
"""
