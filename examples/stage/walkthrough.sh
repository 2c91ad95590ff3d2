#!/usr/bin/env bash
# The walk-through of docs/stage.md, through the command line only:
# identify the stage -> start from the model (nothing learned yet) -> trials -> finish ->
# a moved, rotated copy of the path starts warm from what was learned.
#
#   bash examples/stage/walkthrough.sh [WORKDIR]      (default: ./stage-walkthrough)
#
# PRIMLIB overrides how primlib is run (default: python -m primlib).
set -euo pipefail
S=$(cd "$(dirname "$0")" && pwd)
WORK=${1:-stage-walkthrough}
PRIMLIB=${PRIMLIB:-python -m primlib}
STAGE="python $S/stage.py"
mkdir -p "$WORK"
cd "$WORK"
export PRIMLIB_DB=$PWD/stage.duckdb
rm -f "$PRIMLIB_DB" "$PRIMLIB_DB.wal"

# 1. identify the stage from one experiment (it starts at rest at x = 100, y = 100 mm)
$PRIMLIB machine excite --duration 8 --amplitude 2 --axes 2 --dt 0.002 --out excite.csv
$STAGE --start 100,100 excite.csv record.csv
$PRIMLIB machine identify --input excite.csv --output record.csv --name stage --out stage-id.json
$PRIMLIB machine add stage-id.json

# 2. a series for the glyph: the library is empty, so the first input is the model inverse
$PRIMLIB trials start "$S/glyph.csv" --machine stage --margin 0.5 --out glyph-u0.csv

# 3. trials on the stage until the stop rule says converged
$PRIMLIB trials run 1 --trial-command "$STAGE --start 40,25 {input} {output}" --max-trials 20
$PRIMLIB trials status 1

# 4. store the converged pair as a primitive
$PRIMLIB trials finish 1

# 5. the library grows with use: the glyph rotated by 35 degrees and moved to (120, 60)
#    starts from the warm start; for comparison, a series from the model inverse
$PRIMLIB trials start "$S/glyph-moved.csv" --machine stage --out moved-u0.csv
$PRIMLIB trials start "$S/glyph-moved.csv" --machine stage --inverse --out moved-inverse-u0.csv
$PRIMLIB trials run 2 --trial-command "$STAGE --start 120,60 {input} {output}" --max-trials 1
$PRIMLIB trials run 3 --trial-command "$STAGE --start 120,60 {input} {output}" --max-trials 1
$PRIMLIB trials status 2
$PRIMLIB trials status 3
$PRIMLIB list

# 6. the figure
python "$S/figure.py" --db "$PRIMLIB_DB" --out stage.png
