from hzval.cli import main

raise SystemExit(main())
