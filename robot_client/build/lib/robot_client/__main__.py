from robot_client.cli import main

main()
