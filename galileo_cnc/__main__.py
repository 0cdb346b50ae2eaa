from galileo_cnc.cli.main import main

raise SystemExit(main())
