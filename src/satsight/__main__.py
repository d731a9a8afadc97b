from satsight.cli import main

main()
