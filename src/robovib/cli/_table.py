"""The CLI's table: never cuts a number in a narrow terminal."""

from __future__ import annotations

from rich.table import Table as _RichTable

__all__ = ["Table"]


class Table(_RichTable):
    """A rich table that never cuts a number: where the columns do not fit the terminal, each
    row is printed as ``header: value`` lines instead (no "…", no exponent lost)."""

    def add_column(self, *args, **kwargs) -> None:
        kwargs.setdefault("overflow", "fold")  # never "…" even where the width estimate is off
        super().add_column(*args, **kwargs)

    def __rich_console__(self, console, options):
        cols = self.columns
        need = (
            sum(
                max([len(str(c)) for c in col.cells] + [len(str(col.header)), 1]) + 3
                for col in cols
            )
            + 1
        )
        if need <= options.max_width or not self.row_count:
            yield from super().__rich_console__(console, options)
            return
        from rich.text import Text

        if self.title:
            yield Text.from_markup(str(self.title), style="bold")
        cells = [list(col.cells) for col in cols]  # rich's public view of a column's cells
        for r in range(self.row_count):
            for col, col_cells in zip(cols, cells, strict=True):
                head = str(col.header).replace("\n", " ")
                yield Text.from_markup(f"  {head}: {col_cells[r]}")
            yield Text("")
        if self.caption:
            yield Text.from_markup(str(self.caption))
