from antisync_cli.cli.app import main

main()
