"""`python -m searchrl.train +model=<a|b|c|diagonal> [algo=a2c] [network=small] [scenario=...] [key=value ...]`
or `python -m searchrl.train +experiment=<recipe>` (conf/experiment/, the recipe of a shipped policy).

The entry point: the OpenMP wait policy (before torch loads), the user's `extensions=` (searchrl/extensions.py), a
`resume=` that is not a folder, a group option that
does not exist and a job that cannot compose named before Hydra runs them, then the app
(searchrl/train/app.py: what a run does and writes).
"""

import sys

from searchrl.omp_wait import set_wait_policy

set_wait_policy(sys.argv)
from searchrl import extensions  # noqa: E402
from searchrl.compose_check import check_jobs_compose  # noqa: E402
from searchrl.multirun import exits  # noqa: E402
from searchrl.shared_schema import check_group_choices  # noqa: E402
from searchrl.train.app import main  # noqa: E402  (loads torch: after the wait policy)
from searchrl.train.command_line import check_resume_argument  # noqa: E402

if __name__ == "__main__":
    with exits():
        extensions.import_from_command_line(sys.argv[1:])  # their parts, before any name is checked
        check_resume_argument(sys.argv[1:])
        check_group_choices(sys.argv[1:])
        check_jobs_compose(sys.argv[1:], "train")
    main()
