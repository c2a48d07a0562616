"""Pages the build writes into docs/ (the task pages, the API reference)."""
import pathlib


def write(folder, texts):
  """Writes `texts` (page name -> Markdown) as folder/<name>.md and removes the
  folder's other pages. A page whose text is unchanged is left alone: its
  modification time is what keeps an incremental build incremental."""
  folder = pathlib.Path(folder)
  folder.mkdir(exist_ok=True)
  for name, text in texts.items():
    path = folder / f"{name}.md"
    if not path.is_file() or path.read_text() != text:
      path.write_text(text)
  for stale in set(folder.glob("*.md")) - {folder / f"{n}.md" for n in texts}:
    stale.unlink()
