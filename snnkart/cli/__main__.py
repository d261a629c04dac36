from snnkart.cli.main import main

main()
