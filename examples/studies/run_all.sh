#!/usr/bin/env bash
# The paper's parameter studies on the free-fall benchmark (Sec. 5, Figs. 7-10).
# Usage: bash examples/studies/run_all.sh [OUT_DIR] [extra sweep options, e.g. --workers 4]
# Each sweep resumes (and a finished single run is kept): run the script again to redo only
# missing or failed runs.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
cases="$here/../free_fall"
out="${1:-studies}"
shift || true
# Fig. 7: the two models, each from its own case file (IPIP with the paper's "zones" rule,
# which case_ipip.toml sets and a coarse-grained case cannot carry)
[ -f "$out/models/cg/summary.json" ]   || beamcontact run "$cases/case_cg_paper.toml" --out "$out/models/cg" --quiet
[ -f "$out/models/ipip/summary.json" ] || beamcontact run "$cases/case_ipip.toml"     --out "$out/models/ipip" --quiet
beamcontact compare "$out/models/cg" "$out/models/ipip" --point A --label CG --label IPIP --out "$out/models/models.png"
beamcontact sweep "$cases/case_ipip.toml" --set contact.penalty=1e5,1e6,1e7         --out "$out/penalty" "$@"
beamcontact sweep "$cases/case_ipip.toml" --set analysis.alpha=0,-0.1,-0.2,-0.33    --out "$out/alpha"   "$@"
beamcontact sweep "$cases/case_cg_paper.toml" --set contact.cutoff=0.25,0.3,0.4         --out "$out/cutoff"  "$@"
